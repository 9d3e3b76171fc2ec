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
uniform sampler2D uFarFaceMap;           // texture space, bilinear: the far face's point (scene units) x valid, valid (gl/thickness.py far_face_points)
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
// over a square of that variance about A (far_face_shadow below, half-width sqrt(3 v),
// 2.9-4.9 mm for h = 2-5 mm in skin). Round 18 (farface18, review18's item 2): the point lookups (A lifted
// 2.5 mm along -Ng, or 0.5 mm along the light) drew a hard red line and a dark patch across the top
// of the back-lit scapha (back-ears, 768 px). There the tissue behind P is ~3.7 mm thick, and behind
// its far face lie 0.7-2.1 mm of air and a second layer of the helix 2.8-3.2 mm thick that shadows it
// (ray cast: the far face sees the light at none of the patch's pixels; the lifted point A - 2.5 mm
// Ng lies inside that layer at 94% of them; benchmarks/farface_occluder.py); along the crease where
// Ng turns, A sweeps across a sliver of the far face that does see the light, one pixel wide on
// screen: the line. Cycles' light diffuses sideways across both (mean red 89 there against 59-61).
// The box's taps stand on the far face itself (round 23, shadowbox23): tap k at the offset delta_k of the
// square on P's tangent plane reads, at its own texel uv_ts + M delta_k (M: the layout's uv per scene unit
// on that plane, texture_space_per_unit), the point X_k where that texel's ray left the tissue
// (uFarFaceMap: gl/thickness.py far_face_points), and counts where X_k lies within h / 2 of A along
// Ng (|Ng.(X_k - A)| <= h / 2, a ramp over FAR_FACE_DEPTH_RAMP of it): the far face about A. A texel whose
// ray left through another surface (around a rounded edge onto the part's back, into the head beside it)
// has its point elsewhere and no weight; no light enters the far face there. Rounds 18-22 put the
// square on two planes perpendicular to Ng through A instead: on a rounded, wedge-shaped part as wide as
// the square (the back-lit lobe, 4.7 mm half-width, its back face turned ~20 degrees from its front and
// meeting the cheek in a crease) half its taps lay inside tissue or over the crease, in the head's
// shadow: the box 0.60 where the far face's own triangles in the box are lit at 0.91 (ray cast,
// benchmarks/far_face_box.py; these taps by the same replica 0.82, on the GPU 0.83 where the
// planes read 0.71).
// Each tap counts the far face lit where either of two points off X_k sees the light (each errs only
// towards shadow): X_k lifted FAR_FACE_LIFT_MM along the far face's outward normal -Ng, since X_k is the
// bilinear mean of its texels' points (between two of them on a curved face it lies inside the tissue)
// and inside the tissue X_k is shadowed by its own far face (beside a thickness step:
// tests/test_translucency_oblique.py); or FAR_FACE_LIFT_ALONG_LIGHT_MM plus half the square's
// half-width along the light, which clears a second layer close behind the far face when the first
// point lies inside it (round 18, farface18: the back-lit scapha; benchmarks/farface_occluder.py).
// An occluder is missed only if it lies within those lifts of the far face; occluders centimetres
// away (the head behind an ear) still shadow it. Each tap is one bilinear compare (as shadow_box_curved's, a
// 6 x 6 grid turned by atan(1/6), common/shadow.glsl) against its point's depth less the far face's
// receiver-plane footprint.
const float FAR_FACE_LIFT_MM = 2.5;
const float FAR_FACE_LIFT_ALONG_LIGHT_MM = 0.5;
const vec2 FAR_FACE_DEPTH_RAMP = vec2(0.4, 0.6);  // x h: |Ng.(X_k - A)| from full weight to none

// Texture-space uv per scene unit on the tangent plane spanned by a pixel's screen derivatives
// (dP/dx, dP/dy scene units, duv/dx, duv/dy): the least-squares map M with duv = M dP, M =
// U (Pm^T Pm)^-1 Pm^T. Take the derivatives of the plain (affine per triangle) interpolants, in
// uniform control flow. 0 where the derivatives are degenerate (then every tap reads P's own texel).
mat3x2 texture_space_per_unit(vec3 dPdx, vec3 dPdy, vec2 duvdx, vec2 duvdy) {
    mat2x3 Pm = mat2x3(dPdx, dPdy);
    mat2 G = transpose(Pm) * Pm;
    float det = determinant(G);
    if (!(abs(det) > 1e-30)) return mat3x2(0.0);
    return mat2(duvdx, duvdy) * inverse(G) * transpose(Pm);
}

// The far face's lit fraction over the square of half-width half_mm about A = P - h Ng (above): the
// weighted mean of the taps whose far-face point lies about A. 1 where the light casts no shadow or A
// lies outside its map; 0 where no tap finds the far face.
float far_face_shadow(int i, vec3 P, vec3 Ng, vec2 uv_ts, mat3x2 M, float h_mm, float half_mm, vec3 L) {
    vec3 A = P - Ng * (h_mm / uMmPerUnit);
    ShadowReceiver r;
    if (!shadow_receiver(i, A, -Ng, r)) return 1.0;
    float z_foot = 2.0 * length(r.dz) * uShadowParams[i].w;  // the bilinear 2x2 footprint, as shadow_pcf_at
    vec3 t1 = normalize(cross(Ng, abs(Ng.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 t2 = cross(Ng, t1);
    vec3 lift1 = -Ng * (FAR_FACE_LIFT_MM / uMmPerUnit);
    vec3 lift2 = L * ((FAR_FACE_LIFT_ALONG_LIGHT_MM + 0.5 * half_mm) / uMmPerUnit);
    vec2 ramp = FAR_FACE_DEPTH_RAMP * (h_mm / uMmPerUnit);
    float sum = 0.0, wsum = 0.0;
    for (int ky = 0; ky < SHADOW_BOX_GRID; ++ky) {
        for (int kx = 0; kx < SHADOW_BOX_GRID; ++kx) {
            vec2 g = (vec2(kx, ky) + 0.5) * (2.0 / float(SHADOW_BOX_GRID)) - 1.0;
            vec2 f = SHADOW_BOX_OFFSET(g);
            vec3 delta = (f.x * t1 + f.y * t2) * (half_mm / uMmPerUnit);
            vec4 ff = textureLod(uFarFaceMap, uv_ts + M * delta, 0.0);
            if (ff.w <= 0.0) continue;  // no far face behind this tap's texel
            vec3 X = ff.xyz / ff.w;
            float w = ff.w * (1.0 - smoothstep(ramp.x, ramp.y, abs(dot(X - A, Ng))));
            if (w <= 0.0) continue;  // that texel's far face is not the one about A
            vec3 c1 = r.c + r.J * (X + lift1 - A), c2 = r.c + r.J * (X + lift2 - A);
            float lit = max(shadow_tap(i, c1.xy, c1.z - z_foot), shadow_tap(i, c2.xy, c2.z - z_foot));
            sum += w * lit;
            wsum += w;
        }
    }
    return wsum > 0.0 ? sum / wsum : 0.0;
}

vec3 transmitted_irradiance(vec3 P, vec3 Ng, vec2 uv_ts, mat3x2 uv_per_unit) {
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
        float s = far_face_shadow(i, P, Ng, uv_ts, uv_per_unit, h, half_mm, L);
        T += Ei * (cos_far * s) * T_h;
    }
    return T * uTranslucencyStrength;
}
