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
uniform sampler2D uThicknessMap;         // texture space, bilinear: thickness (mm) x valid, valid (gl/thickness.py)

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

// Irradiance transmitted to P (geometric normal Ng, texture-space uv_ts) from every shadow-casting
// light behind it. The irradiance that enters is the light's at the ENTRY side, E max(N_entry.L, 0),
// which the TSM stores; taking the exit side's -N.L instead lit a band just past every terminator
// of thick parts (eyelid creases, nose), where the entry is grazing and t -> 0.
// The distance through tissue: the TSM's t runs along the light, which through a slab of thickness
// h met at angle theta is h / cos(theta): an ear nearly edge-on to the light transmitted nothing.
// The light diffuses through the thickness, so d = min(t, h) with h the ray-cast thickness behind
// P along -N (geometry/thickness.py) - exact for a slab at any angle (T(h) cos(theta), as tsd) -
// where t agrees with a slab of thickness h: t <= 1.5 h / |N.L| + 1 mm (fading out by 2.5 h / |N.L|).
// A longer t means the light's path left the tissue (the head behind a back-lit ear): t is kept.
// Near terminators of thick parts h >= t, so d = t as before: no lines.
vec3 transmitted_irradiance(vec3 P, vec3 Ng, vec2 uv_ts) {
    vec3 T = vec3(0.0);
    if (uTranslucencyStrength <= 0.0) return T;
    vec2 th = texture(uThicknessMap, uv_ts).xy;
    float h = th.y > 0.25 ? th.x / th.y : -1.0;  // mm; -1: no far face within reach
    for (int i = 0; i < uLightCount; ++i) {
        if (uLightRadiance[i].w < 0.5) continue;  // no shadow map, no thickness
        vec3 L;
        vec3 Ei = light_incident(i, P, L);
        // facing away from the light; the ramp avoids a seam at the terminator (as tsd did)
        float cos_exit = -dot(Ng, L);
        float away = smoothstep(0.0, 0.25, cos_exit);
        if (away <= 0.0) continue;
        vec2 uv_near;
        float t = tsm_thickness_mm(i, P, uv_near);
        if (t < 0.0) continue;
        // 1 where t agrees with the slab, fading to 0 (keep t) between 1.5 and 2.5 h / |N.L| + 1 mm
        float slab = h < 0.0 ? 0.0 : 1.0 - smoothstep(1.5, 2.5, (t - 1.0) * max(cos_exit, 1e-3) / max(h, 1e-3));
        float d = mix(t, min(t, h), slab);
        T += Ei * (away * tsm_entry_cosine(i, P)) * transmittance_profile(d);
    }
    return T * uTranslucencyStrength;
}
