// The bounce light between skin surfaces for the techniques without a texture-space irradiance
// (ssss, preintegrated, lambert): E_b = (1/K) sum_k rho E(y_k) per mesh vertex over K baked
// cosine-weighted rays (dermis.geometry.interreflection), gathered once per lighting change from a
// small texture-space rho E (dermis.gl.interreflection.SharedBounce), with its higher orders
// T = E_b + G E_b + G^2 E_b + G^3 E_b (BounceSeries), read per vertex by common/mesh.vert and
// interpolated over the triangles as tsd's splat interpolates the same T (tsd/bounce_splat.frag). Only in programs compiled with DERMIS_INTERREFLECTION: the others are the
// old programs, unchanged ([scene] interreflection = false).
// It is an irradiance from the whole hemisphere, like the ambient: it enters at k = 1 (the
// directional albedo's hemispherical average) and without a terminator, a shadow edge or normal-map
// detail, so nothing of preintegrated's tables applies to it (dermis/techniques/preintegrated.py).
#ifdef DERMIS_INTERREFLECTION
#ifndef DERMIS_MESH_VARYINGS  // else declared there (common/mesh_varyings.glsl)
in vec3 v_bounce;
#endif

vec3 bounce_irradiance() {
    return max(v_bounce, vec3(0.0));
}
#endif
