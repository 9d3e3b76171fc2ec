// Pre-integrated skin (Penner & Borshukov 2011, GPU Pro 2 ch. II.1), in one mesh pass: the
// profile's scattering comes from lookup tables built at start-up (dermis/techniques/preintegrated.py),
//   diffuse = albedo / pi * (1 - rho_s a(N.V, m) / pi)
//             * [ k(N.V) ( sum_lights E_i D(N_c.L, curvature)_c P(shadow_soft, penumbra width)_c k(N.L)
//                                         (1 - rho_s a(N.L, m) / pi)
//                          + ambient(N_c) )
//                 + transmitted ]                                                  per channel c
//   specular = common/skin_specular.glsl (shared by every skin technique)
// N_c: the normal map filtered by channel c's profile, a mip level per Gaussian (Penner's blurred
// normals, red blurriest; the cosine's tilt from the smooth normal weighted by bump_shadowing, so that
// below the smooth terminator only Penner's wrap lights); D: light wrapped around a ring of the local
// curvature; P: the soft
// shadow's penumbra scattered with the profile (red reaches furthest into the shadow); k: the
// skin's directional albedo (common/directional_albedo.glsl; the ambient enters at k = 1, the light
// through thin parts leaves Lambertian, as in tsd). Per channel, D P is raised to at least the light
// the shadow map's lit points scatter across a concave fold (fold_scattered_light, below).
// first: the varyings on the fragment's own triangle (before any code that reads them)
#include "common/mesh_varyings.glsl"
#include "common/surface.glsl"
#include "common/noise.glsl"
#include "common/shadow.glsl"
#include "common/environment.glsl"
#include "common/energy.glsl"
#include "common/skin_specular.glsl"
#include "common/transmittance.glsl"
#include "common/directional_albedo.glsl"
#include "common/interreflection.glsl"
#include "common/subsurface_transfer.glsl"

uniform sampler2D uDiffuseTable;   // D(N.L, curvature): s = N.L in [-1, 1], t = sqrt(curvature / max)
uniform sampler2D uPenumbraTable;  // P(shadow, width): s = shadow in [0, 1], t = log-spaced width
uniform sampler2D uNormalMapLod;   // uNormalMap through a sampler without anisotropy (the blurred normals' explicit levels)
uniform float uCurvatureMaxPerMm;
uniform vec2 uPenumbraWidthRangeMm;
uniform vec3 uWideWidthMm;          // per channel, how much the profile's wide part widens a sharp edge: 2 x its rms radius along an axis (mm; preintegrated.wide_widths_mm)
uniform vec3 uNarrowShare;          // per channel, the share of the profile's weight in its narrow Gaussians (preintegrated.profile_part)
uniform float uCurvatureFromMesh;   // 1: the mesh's per-vertex curvature, 0: screen derivatives
uniform float uBlurredNormals;      // 1: per-channel blurred normals, 0: the detailed normal
uniform float uPenumbraScattering;  // 1: scatter the penumbra through its table, 0: plain PCF
uniform float uDirectionalAlbedo;   // 1: the skin's directional albedo (scene.directional_albedo), 0: Lambertian
uniform float uPoreScaleMm;
uniform float uPoreStrength;
uniform int uOutputMode;  // OUTPUT_FULL, _DIFFUSE, _SPECULAR or _CURVATURE (1/mm; dermis.techniques.shared.OutputMode)
out vec4 f_color;


// Texel-centre coordinate: f = 0 and 1 land on the first and last texels' centres.
vec2 table_coord(sampler2D table, vec2 f) {
    vec2 size = vec2(textureSize(table, 0));
    return (clamp(f, 0.0, 1.0) * (size - 1.0) + 0.5) / size;
}

// Penner's D per channel, each channel at its own N.L.
vec3 diffuse_lookup(vec3 ndl, float curvature) {
    float t = sqrt(clamp(curvature / uCurvatureMaxPerMm, 0.0, 1.0));
    return vec3(textureLod(uDiffuseTable, table_coord(uDiffuseTable, vec2(ndl.r * 0.5 + 0.5, t)), 0.0).r,
                textureLod(uDiffuseTable, table_coord(uDiffuseTable, vec2(ndl.g * 0.5 + 0.5, t)), 0.0).g,
                textureLod(uDiffuseTable, table_coord(uDiffuseTable, vec2(ndl.b * 0.5 + 0.5, t)), 0.0).b);
}

// The penumbra texture holds three tables of the same rows (dermis.techniques.preintegrated.penumbra_tables):
// PENUMBRA_PCF, Penner's (the PCF's penumbra, sharpened by at most half); PENUMBRA_BOX_WIDE, the wide
// penumbra's, of the profile's wide Gaussians (a step under the box: the box's ramp is all box, no
// penumbra); PENUMBRA_PCF_NARROW, Penner's of the narrow Gaussians. Texel centres of the chosen block only.
const int PENUMBRA_PCF = 0, PENUMBRA_BOX_WIDE = 1, PENUMBRA_PCF_NARROW = 2;
vec3 penumbra_lookup(float shadow, float width_mm, int block) {
    float t = log(max(width_mm, 1e-6) / uPenumbraWidthRangeMm.x) / log(uPenumbraWidthRangeMm.y / uPenumbraWidthRangeMm.x);
    vec2 size = vec2(textureSize(uPenumbraTable, 0));
    float rows = size.y / 3.0;
    vec2 f = vec2(clamp(shadow, 0.0, 1.0) * (size.x - 1.0) + 0.5,
                  float(block) * rows + clamp(t, 0.0, 1.0) * (rows - 1.0) + 0.5) / size;
    return textureLod(uPenumbraTable, f, 0.0).rgb;
}

// Width (mm) of light i's penumbra on the surface at P: measured from the PCF taps' own gradient
// (common/shadow.glsl, shadow_soft_penumbra; no screen derivatives), bounded by the PCF filter's
// diameter, 2 (softness + 1) texels (the Poisson disc and each tap's bilinear 2x2), in world units
// from the light's projection (uv per world unit = |row 0| / 2w), projected on the surface: from
// that (an edge along the light's projected direction) to that / N.L (across it).
// One shadow-map texel of light i at P, in scene units across the light (uv per world unit = |row 0| / 2w).
float shadow_texel_world(int i, vec3 P) {
    mat4 M = uLightViewProj[i];
    float w = (M * vec4(P, 1.0)).w;
    float row0 = length(vec3(M[0][0], M[1][0], M[2][0]));
    return uShadowParams[i].w * 2.0 * abs(w) / max(row0, 1e-12);
}

float pcf_width_mm(int i, vec3 P) {
    return 2.0 * (uShadowParams[i].x + 1.0) * shadow_texel_world(i, P) * uMmPerUnit;
}

float penumbra_width_mm(int i, vec3 P, float ndl_geometric, float measured_mm) {
    float pcf_mm = pcf_width_mm(i, P);
    return clamp(measured_mm, pcf_mm, pcf_mm / max(ndl_geometric, 0.2));
}

// Penner's penumbra table moves light only within the penumbra it is given: its entries are 0 at
// s = 0 and 1 at s = 1 (dermis.techniques.preintegrated.scattered_shadow), so it presumes a soft
// shadow at least as wide as the scattering (the table's "sharpening" takes the scattering's width
// back out of the penumbra). A channel whose profile widens an edge by more than the PCF filter is
// wide (d'Eon's red: 2.35 mm against ~1.2 mm at the shadow tile 2048 on the head) loses its light
// beyond the filter's reach: a cast shadow narrower than the scattering, the upper lid's on the
// closed eye's slit (~2.5-3.5 mm along the surface, the lid 0.7-2.4 mm above it), went black where
// the light scatters red into it (Cycles, tsd, ssss). For such channels the shadow is box-filtered
// over the PCF width plus the wide part's scattering width (uWideWidthMm: the box holds only the wide
// Gaussians, whose edge widening, red's 3.14 mm, the whole profile's 2.35 mm understated: the box cut
// their tail at half its width, red 0.064 off at 0.35-3 mm from an edge against the closed form, 0.044
// now; benchmarks/RESULTS.md round 21, wide21) on P's tangent plane (common/shadow.glsl,
// shadow_box_curved: the receiver's own curvature lifted out; only the profile's wide Gaussians, the
// narrow ones read from the PCF, below) and read through the wide block's row of that width
// (penumbra_lookup(..., PENUMBRA_BOX_WIDE): a box of width W over the map's step is a ramp of
// width W exactly, so the table's edge is the step itself; with the PCF's ~1.2 mm ramp left in it,
// red fell at the lit side of a cast shadow where green does not, a pale green fringe), blended in
// by a_c = (wide width_c - pcf) / pcf in [0, 1] (none where the PCF already holds the wide part's
// scattering, all where it is at most half of it). Probed first: the box's corners and the PCF value agree (all lit
// or all shadowed) over most of a frame, and then so does the box. Limits: the table reads a shadow narrower than the box as one edge (a 2.5 mm strip's
// centre gets 0.89 of the closed form's red, tests/test_preintegrated.py), the scattered tail beyond
// half the box is cut (the table's rescale), and the box lies on the tangent plane, not the surface.
const float LIFT_MAX_TURN = 0.5;  // radians: the most the receiver's normal turns across the square for the lift
vec3 wide_penumbra_blend(int i, vec3 P) {
    float pcf_mm = pcf_width_mm(i, P);
    return clamp((uWideWidthMm - pcf_mm) / pcf_mm, 0.0, 1.0);
}

float wide_penumbra_width_mm(int i, vec3 P) {
    return pcf_width_mm(i, P) + max(uWideWidthMm.r, max(uWideWidthMm.g, uWideWidthMm.b));
}

#ifdef PREINTEGRATED_FOLDS
// Compiled only where fold_scattering is on (dermis.techniques.preintegrated): off, the gather behind
// its uniform was still ~9% of the pass on llvmpipe (head, 512^2: 815 -> 741 CPU ms without its code),
// which compiles the unrolled lights' every branch.
// ---------------------------------------------------------------- light across concave folds
// Penner's two tables see only P's own curvature ring and P's own shadow value, so no light crosses
// a concave fold: at an eyelid crease or in a nostril every point is either the wall facing away
// from the light (D = 0) or the lit wall inside the fold's own cast shadow (s = 0), where tsd's
// texture-space blur, ssss's screen blur and the surface-integral reference (dermis.reference)
// bring light from the lit wall a millimetre away (benchmarks/RESULTS.md, round 7 "Preintegrated
// eyelid crease"). The reference's scattered irradiance at P is
//     E_s(P) = E_i sum_k w_k int_lit g_k(|P - Q|) cos(theta_Q) dA_Q,   g_k the 2-D Gaussian of variance v_k,
// and cos(theta_Q) dA_Q is area across the light: the shadow map's own texel area, the map holding
// exactly the lit points Q (the gather of translucent shadow maps, Dachsbacher & Stamminger 2003,
// here with the profile at the true 3-D distance). Parameterise the map by a plane through P with
// normal n (map area = n.L x plane area) and sample that plane with Gaussian k's own density,
// g_k(|y|) (a 7-point rule: the centre with weight 1/2 and six points at radius 2 sigma_k, 1/12
// each: exact for the Gaussian's moments to degree 5); the estimate is
//     G_k = n.L sum_j q_j exp(-(|P - Q_j|^2 - |y_j|^2) / 2 v_k),   Q_j the lit point on y_j's light ray.
// n = N (the geometric normal) where N.L >= FOLD_MIN_COS: on a lit plane then Q_j = P + y_j, every
// ratio is 1 and G_k = N.L exactly. Below, n is N turned towards L until n.L = FOLD_MIN_COS, so that
// a wall facing away from the light still spans the map around it. Each Q_j is classed by its height
// h = (Q_j - P).N over P's tangent plane (mm), against FOLD_PLANE_TEXELS map texels:
//   behind (h < -delta): reached through the tissue behind P's surface: the convex ring's wrap (D)
//     and the light through thin parts (common/transmittance.glsl) count it already: left out;
//   in P's plane (|h| <= delta): P's own surface, its lit part around P's shadow: N.L times
//     min(sum_j q_j r_j(actual) / sum_j q_j r_j(P's tangent plane), 1), the second sum the ratios
//     the taps would have on P's tangent plane, so that a lit plane gives N.L at any tilt, and 0
//     where N.L <= 0 (a plane facing away holds no lit points);
//   above (h > delta): other surface facing P, the opposite wall of a fold or an overhang: as is.
// Only Gaussians of sigma_k >= FOLD_MIN_SIGMA_TEXELS map texels: narrower ones are not resolved by
// the map (their share stays with D and the PCF shadow). The light is then max(D S, G) per channel:
// both estimate the same integral, each missing what it cannot see (D S: any geometry beyond P's
// ring and P's own shadow value; G: the unresolved Gaussians and the tissue behind P), so a flat or
// convex lit surface keeps D S (G <= N.L there) and a fold gets what crosses it.
uniform sampler2D uShadowDepth;  // the shadow atlas's depths, read without comparison (a sampler object)
uniform float uFoldScattering;  // 1: light across concave folds (G above), 0: Penner's D S alone
const float FOLD_MIN_COS = 0.5;
const float FOLD_PLANE_TEXELS = 1.0;
const float FOLD_MIN_SIGMA_TEXELS = 2.0;
const float FOLD_MAX_EXPONENT = 4.0;
const float SIXTH_TURN = 1.0471976;  // pi / 3: the hexagon's step (radians)  // the rule's radius 2 sigma gives 2; the texel snap adds < 1

// The lit point Q the map of light i holds at the map position of P + y (scene units), on the centre
// of its texel, and y' = the point of n's plane on Q's light ray (so that on a plane Q = P + y'
// exactly). Out, in mm^2 / mm: dq2 = |Q - P|^2, dy2 = |y'|^2, h = (Q - P).N, dflat2 = |Qf - P|^2 with
// Qf the point of P's tangent plane on the same ray. False where y leaves the tile or the map
// holds nothing there.
bool fold_tap(int i, mat4 Minv, vec3 c, mat3 J, vec3 P, vec3 n, vec3 N, vec3 y,
              out float dq2, out float dy2, out float h, out float dflat2) {
    dq2 = dy2 = h = dflat2 = 0.0;
    float tile = 1.0 / uShadowParams[i].w;
    vec2 t = floor((c.xy + (J * y).xy) * tile);
    if (any(lessThan(t, vec2(0.0))) || any(greaterThanEqual(t, vec2(tile)))) return false;
    ivec2 texel = ivec2(uShadowTile[i].xy * vec2(textureSize(uShadowDepth, 0)) + 0.5) + ivec2(t);
    float d = texelFetch(uShadowDepth, texel, 0).r;
    if (d >= 1.0) return false;  // cleared: nothing there
    vec4 q = Minv * vec4(vec3((t + 0.5) / tile, d) * 2.0 - 1.0, 1.0);
    vec3 Q = q.xyz / q.w;
    vec3 Lq;
    light_incident(i, Q, Lq);
    float ln = dot(Lq, n), lN = dot(Lq, N);
    if (abs(ln) < 1e-3) return false;
    vec3 X = Q - (dot(Q - P, n) / ln) * Lq;
    vec3 Xf = lN > 1e-3 ? X - (dot(X - P, N) / lN) * Lq : X;
    float s = uMmPerUnit;
    dq2 = dot(Q - P, Q - P) * s * s;
    dy2 = dot(X - P, X - P) * s * s;
    dflat2 = dot(Xf - P, Xf - P) * s * s;
    h = dot(Q - P, N) * s;
    return true;
}

// G of the comment above, per channel, as a fraction of light i's irradiance E_i.
vec3 fold_scattered_light(int i, vec3 P, vec3 N, vec3 L) {
    if (uLightRadiance[i].w < 0.5) return vec3(0.0);  // no shadow map: nothing to gather
    vec3 c;
    mat3 J;
    if (!shadow_coords_jacobian(i, P, c, J)) return vec3(0.0);
    mat4 Minv = inverse(uLightViewProj[i]);
    float texel_mm = shadow_texel_world(i, P) * uMmPerUnit;
    float delta = FOLD_PLANE_TEXELS * texel_mm;
    float nl = dot(N, L);
    vec3 n = N;
    if (nl < FOLD_MIN_COS) {  // N turned towards L in their plane until n.L = FOLD_MIN_COS
        vec3 b = N - nl * L;
        float bl = length(b);
        b = bl > 1e-6 ? b / bl : normalize(cross(L, abs(L.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
        n = FOLD_MIN_COS * L + sqrt(1.0 - FOLD_MIN_COS * FOLD_MIN_COS) * b;
    }
    float nsl = dot(n, L);
    vec3 e1 = normalize(cross(n, abs(n.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 e2 = cross(n, e1);
    float dq0, dy0, h0, df0;
    bool ok0 = fold_tap(i, Minv, c, J, P, n, N, vec3(0.0), dq0, dy0, h0, df0);
    vec3 G = vec3(0.0);
    for (int k = 0; k < uGaussianCount; ++k) {
        float v = uVariances[k];
        float sigma = sqrt(v);
        vec3 wk = uWeights[k];
        if (sigma < FOLD_MIN_SIGMA_TEXELS * texel_mm || max(wk.r, max(wk.g, wk.b)) <= 0.0) continue;
        float above = 0.0, inplane = 0.0, rflat = 0.0;
        for (int j = 0; j < 7; ++j) {
            float q = j == 0 ? 0.5 : 1.0 / 12.0;
            float dq2 = dq0, dy2 = dy0, h = h0, df2 = df0;
            bool ok = ok0;
            if (j > 0) {
                float a = SIXTH_TURN * (float(j - 1) + float(k) / float(uGaussianCount));  // each Gaussian's hexagon turned
                vec3 y = (2.0 * sigma / uMmPerUnit) * (cos(a) * e1 + sin(a) * e2);
                ok = fold_tap(i, Minv, c, J, P, n, N, y, dq2, dy2, h, df2);
            }
            if (!ok) continue;
            float r = exp(min(-(dq2 - dy2) / (2.0 * v), FOLD_MAX_EXPONENT));
            float keep = clamp(h / delta + 1.0, 0.0, 1.0);  // 0 behind P's plane
            float up = clamp(h / delta - 1.0, 0.0, 1.0);  // 1 above it
            above += q * up * r;
            inplane += q * (keep - up) * r;
            rflat += q * exp(min(-(df2 - dy2) / (2.0 * v), FOLD_MAX_EXPONENT));
        }
        // P's own plane: N.L times its lit fraction, at most 1 (the snap to texel centres can leave
        // the rule's flat sum near 0 at grazing light, where the ratio would then be noise)
        float own = nl > 0.0 ? nl * min(inplane / max(rflat, 1e-6), 1.0) : 0.0;
        G += wk * (nsl * above + own);
    }
    return G;
}
#endif  // PREINTEGRATED_FOLDS

// Light i's share of the irradiance entering the skin at v_world: Penner's D S (at least what crosses
// a fold), times the energy the specular leaves and k(N.L); 0 where the light adds nothing.
vec3 preintegrated_light(int i, vec3 Ngeo, vec3 N, vec3 N_red, vec3 N_green, vec3 N_blue, float curvature,
                         float rho_s, float m, vec3 c) {
    vec3 L;
    vec3 Ei = light_incident(i, v_world, L);
    // Penner's wrap belongs to the smooth surface (Ngeo, its curvature); the normal map's detail tilts
    // each channel's cosine only as far as the smooth surface lets light reach its facets: the tilt
    // weighted by bump_shadowing (common/shadow.glsl, Conty Estevez et al. 2019), which fades to 0 at
    // the smooth terminator, so below it no facet turned toward the light adds light (the jaw's underside
    // lit through the head in the side view; lambert, tsd and ssss take the same term on their N.L)
    float ngl = dot(Ngeo, L);
    vec3 cos_c = vec3(dot(N_red, L), dot(N_green, L), dot(N_blue, L));
    cos_c = ngl + vec3(bump_shadowing(Ngeo, N_red, L), bump_shadowing(Ngeo, N_green, L),
                       bump_shadowing(Ngeo, N_blue, L)) * (cos_c - ngl);
    vec3 D = diffuse_lookup(cos_c, curvature);
    vec3 light = vec3(0.0);  // Penner's D S, then at least what crosses a fold (G)
    if (max(D.r, max(D.g, D.b)) > 0.0) {
        float width_mm;
        float s = shadow_soft_penumbra(i, v_world, Ngeo, width_mm);
        vec3 S = vec3(s);
        bool in_penumbra = uPenumbraScattering > 0.5 && s > 0.0 && s < 1.0;
        float pcf_penumbra_mm = in_penumbra ? penumbra_width_mm(i, v_world, dot(Ngeo, L), width_mm) : 0.0;
        if (in_penumbra) S = penumbra_lookup(s, pcf_penumbra_mm, PENUMBRA_PCF);
        vec3 a = uPenumbraScattering > 0.5 ? wide_penumbra_blend(i, v_world) : vec3(0.0);
        if (max(a.r, max(a.g, a.b)) > 0.0) {
            float W = wide_penumbra_width_mm(i, v_world);
            // 2 x the mesh's curvature: the mean |normal curvature| over a vertex's edges is at least half
            // the larger principal curvature on well-shaped triangles (a cylinder's: half, over edges 60
            // degrees apart), and the lift must hold the surface's steepest rise. At most LIFT_MAX_TURN /
            // half-width: a surface whose normal turns further across the square is a fold, whose walls do
            // shadow each other (the slit); the quadric's lift there (up to 1.9 mm at the chin's crease, the
            // vertex curvature 0.66-1.1 / mm) ignored real occluders: a red speck in the side view's black
            // shadow under the chin, (228, 654) at 768 px, 8-bit red 2 -> 32
            float s_wide = shadow_box_curved(i, v_world, Ngeo, 0.5 * W, min(2.0 * curvature, LIFT_MAX_TURN / (0.5 * W)), s);
            // each Gaussian's light from the shadow filtered at its own reach: the wide ones' from the box,
            // the narrow ones' from the PCF, whose penumbra holds them (Penner's premise). One box for the
            // whole profile read at a lit wedge's tip between two cast shadows (the box ~3.4 mm, the wedge
            // narrower) put red's narrow half as deep in the shadow as its wide tail: red 0.07 of the lit
            // plane's where the closed form gives 0.49 and green 0.72, an olive (cyan on a grey plane)
            // tip (tests/test_preintegrated.py's wedge; the side close-up's concha, benchmarks/RESULTS.md round 20 olive20)
            vec3 S_wide = s_wide > 0.0 && s_wide < 1.0 ? penumbra_lookup(s_wide, W, PENUMBRA_BOX_WIDE) : vec3(s_wide);
            vec3 S_narrow = in_penumbra ? penumbra_lookup(s, pcf_penumbra_mm, PENUMBRA_PCF_NARROW) : vec3(s);
            S = mix(S, mix(S_wide, S_narrow, uNarrowShare), a);
        }
        light = D * S;
    }
#ifdef PREINTEGRATED_FOLDS
    if (uFoldScattering > 0.5) light = max(light, fold_scattered_light(i, v_world, Ngeo, L));
#endif
    if (max(light.r, max(light.g, light.b)) <= 0.0) return vec3(0.0);
    // k(N.L) outside the table, on each light's contribution: D integrates the profile over the
    // ring of the local curvature, where the entry cosine runs around N.L; k could go inside
    // that integral only with the albedo as a third axis (c depends on it, per texel). k is linear
    // in mu with |c| <= 0.18, so taking it at the centre's N.L is exact on a flat surface and
    // off by c times the ring's profile-weighted spread of the cosine on a curved one. N.L is
    // the detailed normal's (the energy term's, tsd's); where the ring wraps light past the
    // terminator (N.L <= 0) k is the grazing one, k(0), which is where that light entered.
    float ndl = clamp(dot(N, L), 0.0, 1.0);
    return Ei * light * energy_transmitted(rho_s, ndl, m) * directional_factor(c, ndl);
}

void main() {
    load_mesh_varyings();
    vec3 Ngeo = normalize(v_normal);
    vec3 P_mm = v_world * uMmPerUnit;
    // curvature (1/mm): the mesh's, or Penner's length(fwidth(N)) / length(fwidth(P)). Every screen
    // derivative here is the fine one (per pixel, not per 2x2 quad): GLSL leaves plain dFdx / fwidth
    // to the implementation, which picks coarse or fine per GPU.
    // The derivatives are the plain interpolants' (common/mesh_varyings.glsl: affine per triangle, so
    // an edge fragment moved onto its triangle keeps its quad's differences).
    vec3 P_raw_mm = mesh_raw_world * uMmPerUnit;
    float curvature_derivatives = length(fwidthFine(normalize(mesh_raw_normal))) / max(length(fwidthFine(P_raw_mm)), 1e-9);
    float curvature = uCurvatureFromMesh > 0.5 ? abs(v_curvature) : curvature_derivatives;
    // the normal map's texels per mm (square root of the area ratio of a pixel's footprint)
    vec2 tex = vec2(textureSize(uNormalMap, 0));
    vec2 nuv = normal_map_uv(v_uv);  // the normal map's own coordinates (its UV set and transform)
    vec2 nuv_raw = normal_map_uv(mesh_raw_uv);
    vec2 duvx = dFdxFine(nuv_raw) * tex, duvy = dFdyFine(nuv_raw) * tex;
    float area_uv = abs(duvx.x * duvy.y - duvx.y * duvy.x);
    float area_mm = length(cross(dFdxFine(P_raw_mm), dFdyFine(P_raw_mm)));  // a pixel's footprint, mm^2
    float texels_per_mm = sqrt(area_uv / max(area_mm, 1e-12));

    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    // blurred normals: channel c's normal is the normal map filtered by channel c's own profile,
    // sum_k w_ck (the map filtered by Gaussian k), each Gaussian the mip level whose box has its
    // standard deviation (level L averages 2^L texels, a box of standard deviation 2^L / sqrt(12)),
    // never finer than the pixel's own footprint: the level of the OpenGL 4.5 spec's (8.14)
    // isotropic formula, log2 of the longer of the two texel-space derivatives (textureQueryLod is
    // allowed to approximate it, and GPUs do). Not one level at the profile's rms radius: that is
    // set by the wide tail (red 1.18 mm) and wiped out the third of red's weight within 0.25 mm,
    // so red lost all the bumps that green and blue kept; at a terminator, where N.L magnifies the
    // bumps, that drew red/green grain (issue 12, the back-lit head behind the ear).
    float footprint_lod = 0.5 * log2(max(max(dot(duvx, duvx), dot(duvy, duvy)), 1e-12));
    mat3 n_profile = mat3(0.0);  // columns: red, green, blue; tangent-space sums
#ifdef PREINTEGRATED_GAUSSIANS
    // the profile's count as a constant (dermis.techniques.preintegrated compiles one program per
    // count; it equals uGaussianCount): the loop's trip count known, -7% of the pass on llvmpipe
    const int gaussians = PREINTEGRATED_GAUSSIANS;
#else
    int gaussians = uGaussianCount;
#endif
    for (int k = 0; k < gaussians; ++k) {
        float box_texels = sqrt(uVariances[k]) * texels_per_mm * 3.4641016;  // sqrt(12) sigma_k
        float lod_k = max(log2(max(box_texels, 1.0)) * uBlurredNormals, footprint_lod);
        vec3 m_k = textureLod(uNormalMapLod, nuv, lod_k).xyz * 2.0 - 1.0;
        n_profile += mat3(m_k * uWeights[k].r, m_k * uWeights[k].g, m_k * uWeights[k].b);
    }
    vec3 N_red = tangent_to_world(v_normal, v_tangent, n_profile[0]);
    vec3 N_green = tangent_to_world(v_normal, v_tangent, n_profile[1]);
    vec3 N_blue = tangent_to_world(v_normal, v_tangent, n_profile[2]);

    vec3 V = normalize(uCameraPos - v_world);
    float m = roughness_at(v_uv);
    float rho_s = specular_intensity(v_uv);
    vec3 Ns = pore_normal(N, P_mm, uPoreScaleMm, uPoreStrength);
    float ndv = clamp(dot(Ns, V), 0.0, 1.0);

    vec3 albedo = albedo_at(v_uv);
    vec3 c = uDirectionalAlbedo * directional_c(albedo);
    vec3 E = vec3(0.0);
    DERMIS_FOR_EACH_LIGHT(E += preintegrated_light(light_i, Ngeo, N, N_red, N_green, N_blue, curvature, rho_s, m, c);)
    vec3 ambient = vec3(environment_irradiance_occluded(N_red, Ngeo, v_visibility).r,
                        environment_irradiance_occluded(N_green, Ngeo, v_visibility).g,
                        environment_irradiance_occluded(N_blue, Ngeo, v_visibility).b);
    E += ambient * energy_transmitted(rho_s, 0.5, m);
#ifdef DERMIS_INTERREFLECTION
    E += bounce_irradiance();  // one bounce: as smooth as the profile's reach, no table (common/interreflection.glsl)
#endif
    // the exit's k(N.V) on the reflected light; the light through a thin part leaves Lambertian
    E = E * directional_factor(c, ndv) + transmitted_irradiance(v_world, Ngeo, v_uv_ts);

    // + the baked subsurface transfer of thin, curled parts (common/subsurface_transfer.glsl: light
    // leaving the skin, gathered from rho E, so not times the albedo again)
    vec3 diffuse = (E * albedo + subsurface_transfer(v_uv_ts) + subsurface_transfer_view(v_uv_ts, V, Ngeo)) * INV_PI * energy_transmitted(rho_s, ndv, m);
    vec3 spec = skin_specular_radiance(v_world, Ngeo, Ns, V, m, rho_s, uSpecularTables, v_visibility,
                                       v_blocked_sh0, v_blocked_sh1, v_blocked_sh2);
    vec3 color = uOutputMode == OUTPUT_DIFFUSE ? diffuse : uOutputMode == OUTPUT_SPECULAR ? spec
                : uOutputMode == OUTPUT_CURVATURE ? vec3(curvature) : diffuse + spec;
    f_color = vec4(color, 1.0);
}
