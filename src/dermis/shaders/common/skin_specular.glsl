// The skin's specular reflection, shared by every skin technique (tsd, ssss, preintegrated): it is
// added AFTER scattering, since the oil layer reflects before any light enters the skin.
// Radiance is physical: d'Eon's KS_Skin_Specular (no 1/pi) divided by pi.
#include "common/shadow.glsl"
#include "common/environment.glsl"
#include "common/brdf.glsl"
#include "common/energy.glsl"

// d'Eon & Luebke 2007 (GPU Gems 3, 14.3): sum over lights of E_i * SHARP shadow * KS_Skin_Specular
// / pi on the (pore-detailed) normal Ns, plus the environment's specular: the environment
// prefiltered for the lobe at the reflected direction (skin_environment_specular, common/environment.glsl)
// times the specular albedo rho_s a(N.V, m) / pi (Karis 2013's split sum).
// The environment's term is scaled by the specular occlusion of common/environment.glsl.
// P: world position; Ng: geometric normal (shadow lookups, back-facing lights); V: to the eye;
// vis: the ambient visibility (ambient occlusion, visible fraction of the irradiance).
// The sharp shadow of light i at P: shadow_sharp unless the including shader gives its own
// (tsd/final.frag: the shadow stored in texture space, tsd/sharp_shadow.glsl).
#ifndef SPECULAR_SHADOW
#define SPECULAR_SHADOW(i, P, Ng) shadow_sharp(i, P, Ng)
#endif
// Light i's share; 0 where it lies behind the geometric surface.
vec3 skin_specular_light(int i, vec3 P, vec3 Ng, vec3 Ns, vec3 V, float m, float rho_s, sampler2D beckmannTex) {
    vec3 L;
    vec3 Ei = light_incident(i, P, L);
    if (dot(Ng, L) <= 0.0) return vec3(0.0);
    return Ei * SPECULAR_SHADOW(i, P, Ng) * ks_skin_specular(Ns, L, V, m, rho_s, beckmannTex) * INV_PI;
}

// The lights through DERMIS_FOR_EACH_LIGHT (common/lights.glsl): written out at constant indices in
// the programs compiled per light count (SKIN_LIGHT_COUNT; preintegrated's: its pass -8% on llvmpipe,
// benchmarks/RESULTS.md, round 11, perf11), the loop over uLightCount elsewhere; the same sum in the
// same order.
// vis, b0..b2: the interpolated in_visibility and in_blocked_sh0..2 (common/environment.glsl); Ng the
// interpolated vertex normal (the bake's), Ns the shading normal.
vec3 skin_specular_radiance(vec3 P, vec3 Ng, vec3 Ns, vec3 V, float m, float rho_s, sampler2D beckmannTex, vec4 vis,
                            vec3 b0, vec3 b1, vec3 b2) {
    vec3 spec = vec3(0.0);
    DERMIS_FOR_EACH_LIGHT(spec += skin_specular_light(light_i, P, Ng, Ns, V, m, rho_s, beckmannTex);)
    float ndv = clamp(dot(Ns, V), 0.0, 1.0);
    spec += skin_environment_specular(Ns, V, m) * rho_s * rho_dt_lookup(uSpecularTables, ndv, m) * INV_PI
            * specular_occlusion_sh(reflect(-V, Ns), normalize(Ng), b0, b1, b2);
    return spec;
}
