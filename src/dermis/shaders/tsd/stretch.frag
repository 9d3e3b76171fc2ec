// Stretch map (d'Eon & Luebke 2007, 14.4.2): texels per millimetre along u and v, from the
// screen-space derivatives of the world position (in mm) while rasterising in UV space, where
// one pixel IS one texel. The blur's tap spacing is sigma_mm * stretch texels.
// z: the cosine of the angle between the surface directions of u and v (dP/du . dP/dv over their
// lengths). A layout need not be orthogonal on the surface (the head's scan UVs beside the nose:
// median |cos| 0.31, 90th percentile 0.76); tsd/blur.frag's V pass steps along the texel direction
// that is orthogonal to u ON THE SURFACE, so the separable blur stays isotropic in mm.
uniform float uMmPerUnit;
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
out vec4 f_stretch;
void main() {
    vec3 p_mm = v_world * uMmPerUnit;
    vec3 pu = dFdx(p_mm), pv = dFdy(p_mm);  // mm per texel along u, v (affine per triangle)
    float du = length(pu);
    float dv = length(pv);
    float c = dot(pu, pv) / max(du * dv, 1e-12);
    f_stretch = vec4(1.0 / max(du, 1e-6), 1.0 / max(dv, 1e-6), c, 1.0);
}
