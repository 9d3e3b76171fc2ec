// Transmittance through thin parts (ears, nostrils) from the shadow map's thickness, for the
// screen-space and pre-integrated techniques: Jimenez, Whelan, Sundstedt & Gutierrez 2010,
// "Real-Time Realistic Skin Translucency" (IEEE CG&A 30(4)). The translucent shadow map holds the
// distance (mm) from the light to the surface it sees first (common/shadow.glsl), so the light
// reaching P from behind crossed d = distance(P) - that of skin. With the profile as a sum of
// Gaussians, G(v, sqrt(r^2 + d^2)) = exp(-d^2 / 2v) G(v, r) and the irradiance that arrives is
//   T(d) = E_light * cos_entry * sum_k w_k exp(-d^2 / 2 v_k)
// per channel (Jimenez's T(s) with dermis's variance convention), the same falloff as tsd's
// translucency, cos_entry from the TSM, the entry side unshadowed; only the wide Gaussians (v_k >= uTranslucencyMinVariance) count, as in tsd:
// the narrow ones carry nothing through millimetres of tissue and would light up the terminator,
// where d goes to 0. The caller multiplies by the albedo (albedo^mix before a blur).
#include "common/shadow.glsl"
#include "common/profile.glsl"

uniform float uTranslucencyMinVariance;  // mm^2
uniform float uTranslucencyStrength;     // 1 = physical, 0 = off

// sum_k w_k exp(-d^2 / 2 v_k) over the wide Gaussians, per channel.
vec3 transmittance_profile(float d_mm) {
    vec3 T = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        if (uVariances[k] < uTranslucencyMinVariance) continue;
        T += uWeights[k] * exp(-d_mm * d_mm / (2.0 * uVariances[k]));
    }
    return T;
}

// Irradiance transmitted to P (geometric normal Ng) from every shadow-casting light behind it.
// The irradiance that enters is the light's at the ENTRY side, E max(N_entry.L, 0), which the TSM
// stores; taking the exit side's -N.L instead lit a band just past every terminator of thick
// parts (eyelid creases, nose), where the entry is grazing and t -> 0. t from common/shadow.glsl,
// tsm_thickness_mm.
vec3 transmitted_irradiance(vec3 P, vec3 Ng) {
    vec3 T = vec3(0.0);
    if (uTranslucencyStrength <= 0.0) return T;
    for (int i = 0; i < uLightCount; ++i) {
        if (uLightRadiance[i].w < 0.5) continue;  // no shadow map, no thickness
        vec3 L;
        vec3 Ei = light_incident(i, P, L);
        // facing away from the light; the ramp avoids a seam at the terminator (as tsd)
        float away = smoothstep(0.0, 0.25, -dot(Ng, L));
        if (away <= 0.0) continue;
        vec2 uv_near;
        float t = tsm_thickness_mm(i, P, uv_near);
        if (t < 0.0) continue;
        T += Ei * (away * tsm_entry_cosine(i, P)) * transmittance_profile(t);
    }
    return T * uTranslucencyStrength;
}
