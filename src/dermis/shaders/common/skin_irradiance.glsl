// The irradiance that enters the skin, shared by the techniques that scatter it (tsd in texture
// space, ssss in screen space): d'Eon & Luebke 2007, 14.4.1 and 14.5.2,
//   E = sum_lights E_i max(N.L, 0) shadow_soft (1 - rho_s a(N.L, m) / pi) + ambient,
// the ambient being the environment's irradiance less the average energy the specular takes
// (a at cos 0.5). The caller multiplies by albedo^mix (pre-scatter colour).
// P: world position; Ng: geometric normal (shadow lookups); N: shading (normal-mapped) normal;
// vis: the ambient visibility (common/environment.glsl), occluding the environment's irradiance.
#include "common/shadow.glsl"
#include "common/environment.glsl"
#include "common/energy.glsl"

// c: the directional albedo's coefficients per channel (common/directional_albedo.glsl), weighting
// each light by k(N.L) = 1 + c (2/3 - N.L); vec3(0) is the Lambertian entry. The ambient is left at
// k = 1: its average over a uniform hemisphere.
vec3 skin_irradiance_directional(vec3 P, vec3 Ng, vec3 N, float rho_s, float m, vec4 vis, vec3 c) {
    vec3 E = vec3(0.0);
    for (int i = 0; i < uLightCount; ++i) {
        vec3 L;
        vec3 Ei = light_incident(i, P, L);
        float ndl = dot(N, L);
        if (ndl <= 0.0) continue;
        E += Ei * ndl * shadow_soft(i, P, Ng) * energy_transmitted(rho_s, ndl, m) * (1.0 + c * (2.0 / 3.0 - ndl));
    }
    E += environment_irradiance_occluded(N, Ng, vis) * energy_transmitted(rho_s, 0.5, m);
    return E;
}

vec3 skin_irradiance(vec3 P, vec3 Ng, vec3 N, float rho_s, float m, vec4 vis) {
    return skin_irradiance_directional(P, Ng, N, rho_s, m, vis, vec3(0.0));
}
