// Transmittance through thin parts (ears, nostrils) for the screen-space and pre-integrated
// techniques (after Jimenez, Whelan, Sundstedt & Gutierrez 2010, "Real-Time Realistic Skin
// Translucency", IEEE CG&A 30(4), with the thickness from a ray-cast bake instead of the shadow
// map). Through tissue d mm thick the irradiance E of the far face arrives as E T(d) / A per
// channel, T the diffusion-theory slab transmittance of the medium the profile describes
// (common/thin_slab.glsl, dermis/profiles/thin_slab.py; d'Eon's sum_k w_k exp(-d^2 / 2 v_k), the
// semi-infinite profile's tail, was 1.7-2.8x under the slab's Monte Carlo through 2-5 mm and
// 2.6-5x under Cycles'), the same law as
// tsd's translucency. The caller multiplies by the albedo (albedo^mix before a blur).
#include "common/shadow.glsl"
#include "common/profile.glsl"

uniform float uTranslucencyMinVariance;  // mm^2
uniform float uTranslucencyStrength;     // 1 = physical, 0 = off
uniform sampler2D uThicknessMap;         // texture space, bilinear: thickness (mm) x valid, valid (gl/thickness.py)
#include "common/thin_slab.glsl"

// The slab law T(d) / A (dermis/profiles/thin_slab.py) per channel: the light through d mm per
// unit irradiance of the far face, over the albedo the caller applies.
vec3 transmittance_profile(float d_mm) {
    return slab_transmittance(d_mm);
}

// Irradiance transmitted to P (interpolated normal Ng, texture-space uv_ts) from every
// shadow-casting light. The light crosses the tissue behind P along -Ng (the profile spreads it
// through the thickness, not along the light), so it enters at the far face A = P - h Ng, h the
// ray-cast thickness (geometry/thickness.py), whose normal is -Ng for a slab: the irradiance that
// enters is E max(-Ng.L, 0) times A's own soft shadow, and T(h) of it arrives at P. Exact for a
// slab at any angle (cos(theta) T(h), as tsd's far-face lookup); the same model as
// tsd/translucency.frag without the far face's blurred irradiance (these techniques have no
// texture-space irradiance to read it from).
// Why not the translucent shadow map's distance t along the light (rounds 1-3): an ear nearly
// edge-on to the light has t many times its thickness, and the switch between t and h (where t
// stopped agreeing with a slab of thickness h) drew a hard-edged, saturated red patch along the
// TSM's texels in the back-lit helix (768 px, preintegrated). Every quantity here is continuous:
// h and its coverage are bilinear in texture space, the cosine and the PCF shadow are smooth.
// Near the terminator of a thick part, h is centimetres (T(h) = 0): no lines there either.
// Where -N finds no far face the bake holds the key light's path through a slab instead
// (geometry/thickness.py: light_thickness, weighted by how antiparallel its faces are): for a slab
// its thickness is the same h and A = P - h Ng lies on the same far face.
// The far face's light is not read at A alone: what arrives at P entered the far face anywhere
// within the slab's lateral spread about A, a per-axis variance v(h) of a few mm^2
// (slab_transmitted_variance, of the channel that crosses the most tissue). So A's shadow is the mean
// over a square of that variance on the far face's tangent plane (shadow_box, half-width sqrt(3 v),
// 2.9-4.9 mm for h = 2-5 mm in skin). Round 18 (farface18, review18's item 2): the point lookups (A lifted
// 2.5 mm along -Ng, or 0.5 mm along the light) drew a hard red line and a dark patch across the top
// of the back-lit scapha (back-ears, 768 px). There the tissue behind P is ~3.7 mm thick, and behind
// its far face lie 0.7-2.1 mm of air and a second layer of the helix 2.8-3.2 mm thick that shadows it
// (ray cast: the far face sees the light at none of the patch's pixels; the lifted point A - 2.5 mm
// Ng lies inside that layer at 94% of them; benchmarks/farface_occluder.py); along the crease where
// Ng turns, A sweeps across a sliver of the far face that does see the light, one pixel wide on
// screen: the line. Cycles' light diffuses sideways across both (mean red 89 there against 59-61).
// The square lies on one of two planes parallel to the far face's, lifted off it, and the far face
// counts as lit where either sees the light (each errs only towards shadow): FAR_FACE_LIFT_MM along
// the far face's outward normal -Ng, since A lies on the surface only within the bake's accuracy (the
// smoothed h is below the texel's own ray median by > 0.7 mm on 10% of the back-lit ear's texels
// thinner than 8 mm, > 1.1 mm on 5%) and A inside the tissue is shadowed by its own far face (beside
// a thickness step: tests/test_translucency_oblique.py); or FAR_FACE_LIFT_ALONG_LIGHT_MM plus half the
// square's half-width along the light, which clears a second layer close behind the far face when the
// first plane lies inside it (the scapha: 94% of the patch's pixels), and the far face's own curve,
// which leaves its tangent plane by r^2 / 2R at r from A (half the half-width where R is the
// half-width; without it the taps compare against the far face itself: speckles). An occluder is
// missed only if it lies within those lifts of the far face; occluders centimetres away (the head
// behind an ear) still shadow it.
const float FAR_FACE_LIFT_MM = 2.5;
const float FAR_FACE_LIFT_ALONG_LIGHT_MM = 0.5;
vec3 transmitted_irradiance(vec3 P, vec3 Ng, vec2 uv_ts) {
    vec3 T = vec3(0.0);
    if (uTranslucencyStrength <= 0.0) return T;
    vec2 th = textureLod(uThicknessMap, uv_ts, 0.0).xy;  // (h x valid, valid), bilinear, one level
    if (th.y <= 0.0) return T;  // no far face within reach
    float h = th.x / th.y;  // mm
    vec3 T_h = transmittance_profile(h) * th.y;  // partial coverage at the bake's edge: fades over a texel
    vec3 A = P - Ng * (h / uMmPerUnit);
    // the spread of the most penetrating channel (the smallest kappa: red in skin), the one whose light arrives
    vec3 v = slab_transmitted_variance(h);
    float v_far = uSlabKappa.r <= min(uSlabKappa.g, uSlabKappa.b) ? v.r : (uSlabKappa.g <= uSlabKappa.b ? v.g : v.b);
    float half_mm = sqrt(3.0 * v_far);  // the box of that variance
    for (int i = 0; i < uLightCount; ++i) {
        if (uLightRadiance[i].w < 0.5) continue;  // no shadow map: the light is not known to reach A
        vec3 L;
        vec3 Ei = light_incident(i, A, L);
        float cos_far = -dot(Ng, L);
        if (cos_far <= 0.0) continue;
        float s = max(shadow_box(i, A - Ng * (FAR_FACE_LIFT_MM / uMmPerUnit), -Ng, half_mm),
                      shadow_box(i, A + L * ((FAR_FACE_LIFT_ALONG_LIGHT_MM + 0.5 * half_mm) / uMmPerUnit), -Ng, half_mm));
        T += Ei * (cos_far * s) * T_h;
    }
    return T * uTranslucencyStrength;
}
