// Stretch map (d'Eon & Luebke 2007, 14.4.2): texels per millimetre along u and v, from the
// screen-space derivatives of the world position (in mm) while rasterising in UV space, where
// one pixel IS one texel. The blur's tap spacing is sigma_mm * stretch texels.
uniform float uMmPerUnit;
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
out vec4 f_stretch;
void main() {
    vec3 p_mm = v_world * uMmPerUnit;
    float du = length(dFdx(p_mm));  // mm per texel along u
    float dv = length(dFdy(p_mm));  // mm per texel along v
    f_stretch = vec4(1.0 / max(du, 1e-6), 1.0 / max(dv, 1e-6), 0.0, 1.0);
}
