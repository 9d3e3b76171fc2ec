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
// A's shadow is looked up FAR_FACE_LIFT_MM off the far face along its outward normal -Ng: A lies
// on the surface only within the bake's accuracy (the smoothed h, a soft minimum over the
// neighbours, is below the texel's own ray median by > 0.7 mm on 10% of the back-lit ear's texels
// thinner than 8 mm, > 1.1 mm on 5%, > 2.4 mm on 1%; bake at 512), and A inside the tissue is
// shadowed by its own far face. That point alone darkened the inner edge of the back-lit helix
// (up to 0.085 of red at 768 px: something within 2.5 mm along -Ng there, another fold of the
// ear, or A beyond the far face when h is long), so the far face counts as lit where either it or
// A + 0.5 mm along the light (rounds 4-6) sees the light: each errs only towards shadow, and an
// occluder is missed only if it lies within 2.5 mm of the far face.
// Not along the light: a lift l along L moves A only l cos_far off the face, 0.1 mm at the ear's
// grazing cos_far = 0.2 (rounds 4-6: 0.5 mm along L, a dark wedge at the top of the back-lit
// helix; tests/test_translucency_oblique.py). Occluders centimetres away (the head behind an
// ear) still shadow it.
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
    for (int i = 0; i < uLightCount; ++i) {
        if (uLightRadiance[i].w < 0.5) continue;  // no shadow map: the light is not known to reach A
        vec3 L;
        vec3 Ei = light_incident(i, A, L);
        float cos_far = -dot(Ng, L);
        if (cos_far <= 0.0) continue;
        float s = max(shadow_soft(i, A - Ng * (FAR_FACE_LIFT_MM / uMmPerUnit), -Ng),
                      shadow_soft(i, A + L * (FAR_FACE_LIFT_ALONG_LIGHT_MM / uMmPerUnit), -Ng));
        T += Ei * (cos_far * s) * T_h;
    }
    return T * uTranslucencyStrength;
}
