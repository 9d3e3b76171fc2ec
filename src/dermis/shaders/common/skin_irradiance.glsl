// The irradiance that enters the skin, shared by the techniques that scatter it (tsd in texture
// space, ssss in screen space): d'Eon & Luebke 2007, 14.4.1 and 14.5.2,
//   E = sum_lights E_i max(N.L, 0) G_bump shadow_soft (1 - rho_s a(N.L, m) / pi) + ambient,
// G_bump the normal map's shadowing by the smooth surface (bump_shadowing, common/shadow.glsl),
// the ambient being the environment's irradiance less the average energy the specular takes
// (a at cos 0.5). The caller multiplies by albedo^mix (pre-scatter colour).
// P: world position; Ng: geometric normal (shadow lookups); N: shading (normal-mapped) normal;
// vis: the ambient visibility (common/environment.glsl), occluding the environment's irradiance.
#include "common/shadow.glsl"
#include "common/environment.glsl"
#include "common/energy.glsl"

#ifdef SKIN_SHARP_SHADOWS
// With SKIN_SHARP_SHADOWS = n defined (tsd's texture-space pass), skin_irradiance also leaves each
// light's SHARP shadow (shadow_sharp, the specular's) here, from the same receiver solve as the
// soft one, for the final pass to read instead of a receiver solve and a tap per light per screen
// sample (d'Eon & Luebke 2007, 14.5.2, compute the shadow once in texture space).
// for lights 0..n-1, n <= 4 (the caller defines it only for scenes of at most n lights). A vector
// written by a select, not an array indexed by the loop's (uniform, not constant) counter: llvmpipe
// keeps such an array in memory and scatters to it lane by lane.
vec4 skin_sharp_shadow;
#endif

// Light i's share of E (d'Eon & Luebke 2007, 14.4.1): E_i max(N.L, 0) G_bump shadow_soft (1 - rho_s a / pi) k(N.L).
// c: the directional albedo's coefficients per channel (common/directional_albedo.glsl), weighting
// each light by k(N.L) = 1 + c (2/3 - N.L); vec3(0) is the Lambertian entry.
vec3 skin_light_terms(vec3 Ei, vec3 L, float ndl, vec3 Ng, vec3 N, float s, float rho_s, float m, vec3 c) {
    return Ei * ndl * bump_shadowing(Ng, N, L) * s * energy_transmitted(rho_s, ndl, m) * (1.0 + c * (2.0 / 3.0 - ndl));
}

vec3 skin_light_entry(int i, vec3 P, vec3 Ng, vec3 N, float rho_s, float m, vec3 c) {
    vec3 L;
    vec3 Ei = light_incident(i, P, L);
    float ndl = dot(N, L);
#ifdef SKIN_SHARP_SHADOWS
    // neither the diffuse (N.L) nor the specular (its own test, Ng.L: common/skin_specular.glsl)
    // uses light i here: skipped before the receiver solve, as the soft shadow alone was (a
    // block of texels all facing away skips the rest: +25% on llvmpipe without it). Stored as 0,
    // unlit: a final-pass sample just on the lit side of the terminator reads it bilinearly
    // (1 there put a lit speck into the back-lit ear's shadowed side, where the map says 0)
    if (ndl <= 0.0 && dot(Ng, L) <= 0.0) return vec3(0.0);
    float sharp;
    float s = shadow_soft_and_sharp(i, P, Ng, ndl > 0.0, sharp);
    skin_sharp_shadow = mix(skin_sharp_shadow, vec4(sharp), equal(ivec4(0, 1, 2, 3), ivec4(i)));
    if (ndl <= 0.0) return vec3(0.0);
#else
    if (ndl <= 0.0) return vec3(0.0);
    float s = shadow_soft(i, P, Ng);
#endif
    return skin_light_terms(Ei, L, ndl, Ng, N, s, rho_s, m, c);
}

// The sum over the lights, plus the ambient (left at k = 1: its average over a uniform hemisphere).
// With SKIN_LIGHT_COUNT = n defined (the scene's light count), the lights are unrolled with CONSTANT
// indices into the uniform arrays (DERMIS_FOR_EACH_LIGHT, common/lights.glsl): on llvmpipe tsd's
// irradiance pass measured 15-30% cheaper (head, side, 5 lights) than the loop over uLightCount
// (benchmarks/RESULTS.md, "Round 9, branch irr9"). The same arithmetic either way.
// In two parts: the lights' sum and the ambient, which depends on no light (the shared bounce,
// tsd/irradiance.frag with SKIN_BOUNCE_INPUTS, keeps the ambient between lighting changes and adds
// the lights' sum to it: the same two sums in the same order).
vec3 skin_lights_directional(vec3 P, vec3 Ng, vec3 N, float rho_s, float m, vec3 c) {
    vec3 E = vec3(0.0);
#ifdef SKIN_SHARP_SHADOWS
    skin_sharp_shadow = vec4(0.0);
#endif
    DERMIS_FOR_EACH_LIGHT(E += skin_light_entry(light_i, P, Ng, N, rho_s, m, c);)
    return E;
}

vec3 skin_ambient(vec3 N, vec3 Ng, float rho_s, float m, vec4 vis) {
    return environment_irradiance_occluded(N, Ng, vis) * energy_transmitted(rho_s, 0.5, m);
}

vec3 skin_irradiance_directional(vec3 P, vec3 Ng, vec3 N, float rho_s, float m, vec4 vis, vec3 c) {
    vec3 E = skin_lights_directional(P, Ng, N, rho_s, m, c);
    E += skin_ambient(N, Ng, rho_s, m, vis);
    return E;
}

vec3 skin_irradiance(vec3 P, vec3 Ng, vec3 N, float rho_s, float m, vec4 vis) {
    return skin_irradiance_directional(P, Ng, N, rho_s, m, vis, vec3(0.0));
}
