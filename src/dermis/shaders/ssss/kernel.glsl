// The screen-space kernel of separable SSS: the active profile's Gaussians, each blurred on its
// own (a sum of 2-D Gaussians is not separable as a whole, but each term is: G(v, r) = g(v, x) g(v, y);
// a single separable kernel for the whole profile, as in Jimenez et al. 2015, is off by 15% for
// d'Eon's red in the r-weighted L2 sense). The horizontal pass writes one image per Gaussian,
// the vertical pass blurs each with the same Gaussian and sums them with the profile's weights.
//
// Widths: a Gaussian of standard deviation sigma (mm) spans sigma * ppm pixels at a point whose
// view depth is z mm, ppm = uPixelsPerMmAtUnitDepth / z (uPixelsPerMmAtUnitDepth = size / 2 * P[i][i]
// = size / (2 tan(fov / 2)) along the blur's axis): Jimenez et al. 2009, eq. 2, whose gradient
// term comes here from following the surface (below).
// Reach: the widest Gaussian is followed out to where it falls below 1e-3 of its peak,
// sqrt(2 ln 1000) = 3.717 sigma (so the whole profile is covered to below 1e-3 of its own peak):
// the last pixel with weight is P = ceil(3.717 sigma_max ppm); each narrower Gaussian is followed only
// to its own reach (the narrow half: ssss_blur, round 24).
// A FIXED number of taps, SSSS_TAPS per side (Jimenez et al. 2015 use 11-25 in all; the cost must not
// grow with the head's size on screen): the pixels 1..P of each side are split into SSSS_TAPS cells,
// cell j = pixels [a_j, a_(j+1)), a_j = max(j + 1, round((P + 1)^(j / SSSS_TAPS)))
// (dermis.techniques.ssss.tap_cells is its twin): one pixel each near the centre, where the
// narrow Gaussians live, and widening geometrically into the wide Gaussians' tails, so every
// Gaussian of the profile (d'Eon's span 34x in sigma) varies little within most of its cells
// (quadratic widths left the narrow Gaussians in 3-pixel cells at 20 px/mm: the impulse 54 %
// off). Where
// P <= SSSS_TAPS every cell is one pixel and the blur is deterministic. A cell of n pixels is
// represented by ONE of them, drawn per pixel (a hash, so the image is stable from frame to
// frame), with n times its weight: stratified sampling, exact in expectation for every pixel
// (each of the cell's pixels is drawn with probability 1 / n), so an impulse's response is the
// profile's on average and smooth light is blurred with fine noise instead of rings (Jimenez et al.
// 2015 jitter their kernels per pixel for the same reason). Draws stratified across neighbouring
// pixels (interleaved gradient noise, Jimenez 2014) were tried: the grain filter below then removes
// a little more (front-key at 768 px, RMS 0.00054 against 0.00067 of the mean), but pixels whose
// draws are correlated gather a single bright pixel coherently: one dot's energy 1.17 in red
// (hash: 1.003), so an isolated highlight would come out 17 % too bright.
// Grain filter (option grain_filter, ssss/grain_filter.frag): the noise lives only in the wide
// Gaussians, whose outer cells span several pixels. A Gaussian that is at least
// SSSS_FILTER_SIGMA_PX wide at a pixel is blurred here with its variance less
// SSSS_FILTER_VARIANCE_PX2 = 1/2 px^2 per axis, and the vertical pass writes the sum of such
// Gaussians apart from the others; the filter pass convolves that sum with the 3 x 3 binomial
// [1 2 1] x [1 2 1] / 16, whose variance is exactly 1/2 px^2 per axis, so the wide Gaussians get
// their full variance back (variances add under convolution; the binomial's higher cumulants are
// small beside a >= 3 px Gaussian's: tests/test_ssss_grain.py) and the narrow ones, which carry the
// skin's sharp detail, are not touched: below 3 px a Gaussian keeps nearly all its weight in the
// one-pixel cells near the centre (d'Eon's profile at 768 px: cells widen from pixel 8), and the
// compensation is <= 1/18 of the variance of those filtered. Where a blur's rejected taps made the
// wide light jump from pixel to pixel (creases), the filter backs off (ssss/grain_filter.frag).
// Weights: a pixel's share of a 1-D Gaussian of sigma (px) is the Gaussian integrated over the
// pixel, i.e. the Gaussian convolved with a 1-pixel box, taken here as the Gaussian of variance
// sigma^2 + 1/12 (the box's variance) at the pixel's centre: within 0.5 % of the integral's
// share for sigma >= 0.5 px, and a sub-pixel Gaussian still keeps its light in its pixel. With
// the depth factor below, every tap costs ONE exp per Gaussian, no erf, and no table that depends
// on the pixel size. Weights are renormalised over the taps used (inside the frame).
//
// Following the surface (Jimenez et al. 2009, sec. 4; 2015, SSSS_FOLLOW_SURFACE): a tap whose
// depth differs by dz mm lies that much further away on the surface, so its weight also carries
// the Gaussian's factor exp(-dz^2 / 2 v_k) (G(v, sqrt(x^2 + dz^2)) = G(v, x) exp(-dz^2 / 2v)),
// and the kernel is renormalised over those taps: a plane slanted by theta gets the Gaussian of
// sigma cos(theta) in screen space, exactly what the surface measure ds = dx / cos(theta) asks.
// Taps with |dz| > uDepthCutoffMm (a silhouette), off the mesh, or across air (below) lie on
// ANOTHER surface: they keep their kernel weight but bring the pixel's OWN light, not the light
// of the far side (Jimenez et al. 2015, SeparableSSS.h, SSSS_FOLLOW_SURFACE: "lerp back to
// colorM"). The surface the kernel would have covered there continues out of sight (under the
// upper lid, around a silhouette), and the pixel's light is the estimate of it that neither
// brightens nor darkens it. Renormalising onto the far side instead filled the closed eye's slit,
// whose few visible pixels are dark and whose walls are hidden, with the lit lower lid's red: an
// orange line 1.87x the reference's red (benchmarks/eyelid_slit.py, RESULTS "Eyelids, ssss cost").
// Energy is kept either way; light neither bleeds across silhouettes nor leaks into the background.
//
// Tissue paths (as dermis.reference's paths = "tissue", TISSUE_TAU in techniques/shared.py): where
// the straight segment between the two surface points leaves either of them into the AIR, more
// than asin(uTissueTau) above its tangent plane (u.N_p > tau or -u.N_q > tau; u the unit offset
// from p to q, N the facets' normals, view space), the light goes round the concave bend between
// them inside the tissue, a longer path, or, where no single bend joins them, q is skipped
// (ssss_tissue_path below). Across a crease (closed
// eyelids, lips, a nostril's rim) the two sides lie a pixel apart on screen and at about the same
// depth, so depth alone let the lit lids' light into the dark crease between them: a thin
// saturated orange line along both eyelid creases, where tsd (whose texture-space neighbours are
// the crease's own walls) and the reference show a dark line. Smooth convex skin keeps every tap
// (its neighbours lie below the tangent plane); concave skin of radius R keeps those within ~R/2.
// A skipped tap brings the pixel's own light (above). Keeping its weight with NO light (the
// crease's hidden walls taken as dark) was tried: the wide red Gaussians lost the most weight,
// and cyan lines appeared along every crease (nose wings, eye sockets).
#include "common/profile.glsl"
// TEXEL: every texture the passes read is NEAREST, CLAMP_TO_EDGE (ssss.py _ensure_targets)
#include "common/texel.glsl"

uniform sampler2D uIrradiance;          // pass 1: rgb pre-scatter irradiance, a = view depth mm (0: none)
uniform float uPixelsPerMmAtUnitDepth;  // along this pass's axis
uniform ivec2 uDirection;               // (1, 0) horizontal, (0, 1) vertical
// SSSS_TAPS: taps (cells) per side, compiled in (the tap loop unrolls)
uniform float uDepthCutoffMm;           // taps whose depth differs more are another surface
uniform float uFollowSurface;           // 1: weigh taps by the depth difference; 0: ignore depth (tests)
uniform sampler2D uViewNormal;          // pass 1: the geometric normal in view space (0: none)
uniform vec2 uPixelsPerMmXY;            // uPixelsPerMmAtUnitDepth along x and y: view-space offsets
uniform float uTissueTau;               // sin of the largest angle above the tangent plane; > 1: off
uniform float uSurfaceMeasure;          // 1: weigh taps by their surface per pixel (below); 0: off

const float SSSS_REACH_SIGMAS = 3.7169;  // sqrt(2 ln 1000): a Gaussian at 1e-3 of its peak
const float SSSS_LOG2_E = 1.4426950409;  // exp(x) = exp2(x log2(e))
// The narrow Gaussians 0..SSSS_NARROW-1, taken only out to their own reach (ssss_blur's two tiers)
#define SSSS_NARROW (MAX_GAUSSIANS / 2)
// SSSS_GRAIN_FILTER (0/1), compiled in: the grain filter (above)
const float SSSS_FILTER_SIGMA_PX = 3.0;      // a Gaussian this wide (px) is blurred less, then filtered
const float SSSS_FILTER_VARIANCE_PX2 = 0.5;  // the binomial [1 2 1] / 4's variance, px^2

struct SsssKernel {
    float ppm;                           // pixels per mm at this pixel's depth
    int last_px;                         // P: the last pixel of each side with weight
    // exp2 arguments, log2(e) folded in (a tap's weight is one exp2 per Gaussian, ssss_blur):
    float x2_coef[MAX_GAUSSIANS];        // -log2(e) / (2 (sigma_k^2 + 1/12)), 1/px^2: a pixel's share (above)
    float dz2_coef[MAX_GAUSSIANS];       // -log2(e) / (2 sigma_k^2), 1/px^2: the depth factor
    int narrow_reach_px;                 // the last pixel of the narrow Gaussians' reach (ssss_blur)
    float jitter;                        // [0, 1): this pixel's draw in its cells
    bool wide[MAX_GAUSSIANS];            // blurred with the filter's variance taken off (grain filter)
};

// Gaussian k (sigma_px at this pixel) goes through the grain filter (above).
bool ssss_filtered(float sigma_px) {
    return SSSS_GRAIN_FILTER != 0 && sigma_px >= SSSS_FILTER_SIGMA_PX;
}

// An integer hash (Wang 1997 / Jenkins' 32-bit mix) -> [0, 1): per pixel and pass.
float ssss_hash01(ivec2 p, int pass_index) {
    uint h = uint(p.x) * 1973u + uint(p.y) * 9277u + uint(pass_index) * 104729u + 1u;
    h = (h ^ 61u) ^ (h >> 16u);
    h *= 9u;
    h ^= h >> 4u;
    h *= 0x27d4eb2du;
    h ^= h >> 15u;
    return float(h >> 8u) / 16777216.0;
}

// The kernel at a pixel p whose view depth is depth_mm; pass_index 0 horizontal, 1 vertical.
SsssKernel ssss_kernel(float depth_mm, ivec2 p, int pass_index, int size_px) {
    SsssKernel K;
    K.ppm = uPixelsPerMmAtUnitDepth / depth_mm;
    float widest = 0.0;
    float narrow_widest = 0.0;  // the narrow Gaussians' widest pixel share's sigma, px
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        float sigma_px = max(sqrt(uVariances[k]) * K.ppm, 1e-4);
        // a pixel's share reaches further than the Gaussian (sigma^2 + 1/12 px^2, above)
        float share_sigma = sqrt(sigma_px * sigma_px + 1.0 / 12.0);
        if (k < SSSS_NARROW) narrow_widest = max(narrow_widest, share_sigma);
        K.wide[k] = ssss_filtered(sigma_px);
        float var_px = sigma_px * sigma_px - (K.wide[k] ? SSSS_FILTER_VARIANCE_PX2 : 0.0);
        K.x2_coef[k] = -SSSS_LOG2_E * 0.5 / (var_px + 1.0 / 12.0);
        K.dz2_coef[k] = -SSSS_LOG2_E * 0.5 / var_px;
        if (k < uGaussianCount) widest = max(widest, sigma_px);
    }
    // at most the frame's size (taps beyond the frame are skipped in any case)
    K.last_px = int(min(ceil(SSSS_REACH_SIGMAS * widest), float(size_px)));
    K.narrow_reach_px = min(int(ceil(SSSS_REACH_SIGMAS * narrow_widest)), K.last_px);
    K.jitter = ssss_hash01(p, pass_index);
    return K;
}

// First pixel of cell j of a side (above); cell SSSS_TAPS starts past the last pixel.
// log2_end = log2(last_px + 1).
int ssss_cell_start(int j, int last_px, float log2_end) {
    if (last_px <= SSSS_TAPS) return j + 1;
    return max(j + 1, int(floor(exp2(log2_end * float(j) / float(SSSS_TAPS)) + 0.5)));
}

// Depth difference of a tap in pixels at this depth, or -1 to reject the tap.
float ssss_tap_dz_px(SsssKernel K, float depth_mm, float tap_depth_mm) {
    if (tap_depth_mm <= 0.0) return -1.0;  // no surface there
    float dz = abs(tap_depth_mm - depth_mm) * uFollowSurface;
    if (dz > uDepthCutoffMm) return -1.0;
    return dz * K.ppm;
}

// View-space position (mm) of pixel p at view depth z_mm (a symmetric perspective frustum):
// x_view = (p + 0.5 - size / 2) z / pixels-per-mm-at-unit-depth, likewise y; z_view = -z.
vec3 ssss_view_position_mm(ivec2 p, ivec2 size, float z_mm) {
    vec2 c = (vec2(p) + 0.5 - 0.5 * vec2(size)) * (z_mm * (1.0 / uPixelsPerMmXY));
    return vec3(c, -z_mm);
}

// Surface measure (uSurfaceMeasure = 1): the profile is integrated over the SURFACE,
// sum_q R(d) E_q dA_q, and a pixel whose surface is inclined to the view holds more of it than one
// facing the camera: along the blur's axis a, ds/dx = sqrt(n_a^2 + n_z^2) / |n_z| (n the view-space
// normal, orthographic approximation), a tap's weight is multiplied by its own ds/dx. For the
// separable pair the product of the two axes' factors stands for the area's 1 / |n_z| (exact where
// the surface tilts along one axis). It matters where the visible surface folds away: the pixels
// at the closed eye's slit are the lids' margins turning into it (n_z 0.5-0.7), dark, and hold
// 1.4-1.9x the surface of a pixel facing the camera (slit red 1.33x -> 1.27x the reference,
// benchmarks/eyelid_slit.py). Facing planes (every impulse test) are unchanged. At most
// SSSS_MAX_MEASURE (n_z >= 0.2): silhouettes stay finite. 1 when not following the surface.
// OFF by default (option surface_measure): on the whole head it moved the environment scene's
// validate FLIP 0.0272 -> 0.0281 (the straight-path reference), so its net effect is not shown
// to be a gain; the eye close-up's mean error against the tissue-path reference 0.0213 -> 0.0205.
const float SSSS_MAX_MEASURE = 5.0;
float ssss_measure(vec3 n) {
#if !SSSS_SURFACE_MEASURE
    return 1.0;
#endif
    if (uFollowSurface == 0.0 || uSurfaceMeasure == 0.0) return 1.0;
    float na = dot(n.xy, vec2(uDirection));
    return min(sqrt(na * na + n.z * n.z) / max(abs(n.z), 1e-6), SSSS_MAX_MEASURE);
}

// The path through the tissue from the pixel's surface point pp (view space, mm, normal np) to
// pixel q's (normal nq) (above), as dermis.reference.integrate._tissue_path (its docstring has the
// derivation): returns s^2 - c^2 in mm^2, how much longer than the straight chord c it is, with
// share the part of the light that takes it; share 0: no path, q is on another surface.
//   h_q = (q - p).N_p, q's height above p's tangent plane; h_p = -(q - p).N_q, p's above q's.
//   Both <= tau c: the chord leaves neither end into the air (flat or convex skin): s = c.
//   Both >= -tau c, one above: a CONCAVE bend. Its chord crosses the air over the valley; the
//     light goes round the bend inside the tissue. On the wedge of the two tangent planes (the
//     sharpest surface those normals allow; fold line along N_p x N_q, phi the angle between the
//     normals) p and q lie a = h_p / sin phi and b = h_q / sin phi from the fold, t apart along
//     it, and the path is straight on the unfolded wedge: s^2 = (a + b)^2 + t^2 (a circular arc
//     is shorter: 1.02 c against the wedge's 1.06 c at phi = 40 degrees). Facing sheets: s -> inf.
//     The wedge's chord across the fold (law of cosines) more than tau from the real one: no
//     wedge joins them. share = clamp(2 N_p.N_q, 0, 1): 1 up to 60 degrees, 0 from 90 (a sharper
//     bend on a mesh is a fold of two tissues, the closed lips' line: 96-120 degrees at 768 px).
//   Otherwise (one end below the other's plane, e.g. parallel normals 2 mm apart: a step): none.
// The normals are the FACETS' (ssss/irradiance.frag): the interpolated ones lag a coarse mesh by
// 15 degrees at the side view's inner eye corner, where two pixels of one facet looked like a step.
// Before the bend's path, every tap across a concave bend was dropped: a hard dark wedge where the
// nose's shadow edge falls on a 45 degree bend at the inner eye corner (RESULTS, round 11 eye11).
float ssss_tissue_path(vec3 pp, vec3 np, ivec2 q, vec3 nq, float zq, ivec2 size, out float share) {
    share = 1.0;
    if (uTissueTau > 1.0) return 0.0;
    vec3 d = ssss_view_position_mm(q, size, zq) - pp;
    float c2 = dot(d, d);
    if (c2 <= 0.0) return 0.0;
    vec3 n_p = np;  // unit (ssss/irradiance.frag normalises them; half floats: 1e-3)
    vec3 n_q = nq;
    float h_q = dot(d, n_p);
    float h_p = -dot(d, n_q);
    // Every test below compares squares (x |x| keeps the sign): no square root, one division
    // (llvmpipe runs every branch's arithmetic for all pixels, so the early returns save nothing).
    // h <= tau c  <=>  h |h| <= tau^2 c^2
    float tol2 = uTissueTau * uTissueTau * c2;
    float sq = h_q * abs(h_q);
    float sp = h_p * abs(h_p);
    if (sq <= tol2 && sp <= tol2) return 0.0;
    share = 0.0;
    if (sq < -tol2 || sp < -tol2) return 0.0;
    vec3 axis = cross(n_p, n_q);  // |axis| = sin phi
    float sin2_phi = dot(axis, axis);
    if (sin2_phi < 1e-6) return 0.0;  // facing sheets (sin phi < 1e-3): s > 250 c, nothing passes
    float inv_sin2 = 1.0 / sin2_phi;
    float dt = dot(d, axis);
    float t2 = dt * dt * inv_sin2;  // t^2, t = d.axis / sin phi
    float hp = max(h_p, 0.0);       // a = hp / sin phi: p's distance from the fold line, mm
    float hq = max(h_q, 0.0);       // b = hq / sin phi: q's
    float cos_phi = dot(n_p, n_q);
    float across2 = max(c2 - t2, 0.0);
    float wedge2 = (hp * hp + hq * hq + 2.0 * hp * hq * cos_phi) * inv_sin2;
    // |wedge - across| > tau across  <=>  wedge > (1 + tau) across or wedge < (1 - tau) across (tau <= 1)
    float hi = 1.0 + uTissueTau;
    float lo = 1.0 - uTissueTau;
    if (wedge2 > hi * hi * across2 || wedge2 < lo * lo * across2) return 0.0;
    share = clamp(2.0 * cos_phi, 0.0, 1.0);
    return max((hp + hq) * (hp + hq) * inv_sin2 + t2 - c2, 0.0);  // (a + b)^2 + t^2 - c^2
}

// True where the tissue joins the pixel to q by the chord or a bend all its light takes, at most
// twice as long as the chord (the grain filter's pairs are a pixel apart: a longer path, or a
// fold, is a crease whose far side is another surface).
bool ssss_same_tissue(vec3 pp, vec3 np, ivec2 q, vec3 nq, float zq, ivec2 size) {
    float share;
    float extra = ssss_tissue_path(pp, np, q, nq, zq, size, share);
    vec3 d = ssss_view_position_mm(q, size, zq) - pp;
    return share >= 1.0 && extra <= 3.0 * dot(d, d);
}

// Pixel q's normal, fetched only when the tissue-path test or the surface measure reads it (they
// return before reading it otherwise: tissue_paths or follow_surface off, surface_measure off).
vec3 ssss_tap_normal(ivec2 q) {
    bool needed = uTissueTau <= 1.0 || (uFollowSurface != 0.0 && uSurfaceMeasure != 0.0);
    return needed ? TEXEL(uViewNormal, q).xyz : vec3(0.0, 0.0, 1.0);
}

// What a pass reads at pixel q: its view depth in mm (0: no surface), its normal (where the
// tissue-path test or the surface measure reads it; ``centre``: always) and each Gaussian's light
// (the horizontal pass: the pre-scatter light for every k, from uIrradiance and uViewNormal; the
// vertical pass: the horizontal pass's packed texels, ssss/packing.glsl, 3 fetches for K = 6
// where the separate images took K + 2) and the rejected share of the horizontal pass there (0 in
// the horizontal pass).
// first_k (a constant): the first Gaussian whose light is read (the vertical pass fetches only the
// texels that hold Gaussians first_k..K-1, ssss/packing.glsl); light[k < first_k] is left undefined.
void ssss_fetch(ivec2 q, bool centre, const int first_k, out float depth_mm, out vec3 normal,
                out vec3 light[MAX_GAUSSIANS], out float rejected);

// The 1-D blur along uDirection at pixel p, per Gaussian: out[k] = sum_taps w E_k / sum_taps w
// (pass_index 0 horizontal, 1 vertical), for a pixel on the skin (depth > 0); wide[k]: Gaussian k
// was blurred for the grain filter (its variance less SSSS_FILTER_VARIANCE_PX2).
// Written so that a GPU compiler keeps everything in registers: every loop over the Gaussians has
// a constant trip count (MAX_GAUSSIANS = the profile's K) and no loop inside, so it unrolls and
// each array is indexed by constants. Per tap: one texel of uIrradiance (depth), the normal where
// the tissue-path test reads it, each Gaussian's light (ssss_fetch) and one exp per Gaussian:
// exp(-(x^2 / 2 (sigma^2 + 1/12) + dz^2 / 2 sigma^2)), the pixel's share times the depth factor.
// A tap on another surface has dz taken as 0 (its kernel weight) and brings the pixel's own light.
//
// rejected: the share of the widest Gaussian's weight that fell on another surface (the pixel's own
// light stood in for it), in this pass and, averaged with the same weights, in the horizontal
// pass at the taps: 1 - (1 - this pass's) (1 - the horizontal pass's). Where it is large the
// blurred light jumps with the pixel's own light from one pixel to the next (beside a crease the
// hidden side continues with each pixel's own light), and the grain filter backs off.
// The sums of a blur (ssss_blur): per Gaussian the weighted light of the taps on the same surface,
// their weight, and the weight whose light is the pixel's own (rejected taps; its own pixel's 1 is
// added at the end); r_sum: the widest Gaussian's weights times the horizontal pass's rejected share.
struct SsssSums {
    vec3 sum[MAX_GAUSSIANS];
    float wsum[MAX_GAUSSIANS];
    float own[MAX_GAUSSIANS];
    float r_sum;
};

// One tap at signed offset i pixels along uDirection, standing for a cell of 2^log2_cell pixels,
// for Gaussians first_k..K-1 (first_k a constant: the loop unrolls over those alone).
void ssss_tap(const int first_k, ivec2 p, int i, float log2_cell, SsssKernel K, float cz, vec3 pp, vec3 np,
              ivec2 size, inout SsssSums S) {
    ivec2 q = p + uDirection * i;
    if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) return;
    float tz;
    vec3 nq;
    vec3 light[MAX_GAUSSIANS];
    float tap_rejected;
    ssss_fetch(q, false, first_k, tz, nq, light, tap_rejected);
    float dz_px = ssss_tap_dz_px(K, cz, tz);
    float share = 0.0;  // of the light that reaches q's surface through the tissue
    float extra = dz_px < 0.0 ? 0.0 : ssss_tissue_path(pp, np, q, nq, tz, size, share);
    // share: 0 on another surface (a rejected tap, dz_px < 0 or no tissue path), in (0, 1] across
    // a bend, 1 elsewhere; its weight's rest (1 - share) brings the pixel's own light (a 60-90
    // degree fold's far side is another tissue)
    bool other = share <= 0.0;
    float x2 = float(i * i);
    // the kernel at the tissue path s: x^2 + dz^2 is the chord c^2, the path round a bend
    // adds s^2 - c^2 (0 elsewhere); a tap on another surface keeps its kernel weight (dz 0)
    float dz2 = other ? 0.0 : dz_px * dz_px + extra * K.ppm * K.ppm;
    float reach = share * ssss_measure(nq);  // the weight's part that brings q's light
    float stay = 1.0 - share;                // the part that brings the pixel's own
    // branch-free: llvmpipe runs both sides of a branch for every pixel and blends each
    // variable they write (round 24, ssss24)
    for (int k = first_k; k < MAX_GAUSSIANS; ++k) {
        // cell * exp(-(x^2 / 2 (sigma^2 + 1/12) + dz^2 / 2 sigma^2))
        float w = exp2(x2 * K.x2_coef[k] + (dz2 * K.dz2_coef[k] + log2_cell));
        S.own[k] += w * stay;
        float wq = w * reach;
        S.sum[k] += wq * light[k];
        S.wsum[k] += wq;
#if SSSS_GRAIN_FILTER
        if (k == MAX_GAUSSIANS - 1) S.r_sum += wq * tap_rejected;
#endif
    }
}

// Cell j (its first pixel start, n pixels) of both sides, for Gaussians first_k..K-1: this pixel's
// draw in it is a golden-ratio sequence from its jitter (decorrelates the cells); the other side
// takes the opposite draw.
void ssss_cell(const int first_k, int j, int start, int n, ivec2 p, SsssKernel K, float cz, vec3 pp, vec3 np,
               ivec2 size, inout SsssSums S) {
    float cell = float(n);
    float log2_cell = log2(cell);  // its tap stands for n pixels: n times the weight
    float u = fract(K.jitter + 0.61803399 * float(j));
    ssss_tap(first_k, p, -(start + min(int(u * cell), n - 1)), log2_cell, K, cz, pp, np, size, S);
    ssss_tap(first_k, p, start + min(int((1.0 - u) * cell), n - 1), log2_cell, K, cz, pp, np, size, S);
}

// The 1-D blur along uDirection at pixel p, per Gaussian: out[k] = sum_taps w E_k / sum_taps w
// (pass_index 0 horizontal, 1 vertical), for a pixel on the skin (depth > 0); wide[k]: Gaussian k
// was blurred for the grain filter (its variance less SSSS_FILTER_VARIANCE_PX2).
// Written so that a GPU compiler keeps everything in registers: every loop over the Gaussians has
// a constant trip count and no loop inside, so it unrolls and each array is indexed by constants.
// Per tap: the texel(s) with q's depth, normal and light (ssss_fetch) and one exp2 per Gaussian:
// exp(-(x^2 / 2 (sigma^2 + 1/12) + dz^2 / 2 sigma^2)), the pixel's share times the depth factor.
// A tap on another surface has dz taken as 0 (its kernel weight) and brings the pixel's own light.
//
// Two tiers (round 24, ssss24): the cells are walked outwards in two loops, the first with every
// Gaussian while a cell starts within the narrow Gaussians' reach (0..SSSS_NARROW-1,
// ceil(3.717 sqrt(sigma^2 + 1/12)) px of the widest of them: its pixel share at 1e-3 of its peak),
// the second with the wide ones (SSSS_NARROW..K-1) out to the last pixel: d'Eon's profile at
// front-key 768 px (P = 50 px, the narrow reach 8 px) 57 of 72 Gaussian-taps, and the vertical
// pass's outer taps fetch only the texels of the wide Gaussians (2 of 3). The narrow Gaussians
// lose the pixels beyond 3.717 of their widths: < 2e-4 of their weight (erfc(3.717 / sqrt 2)),
// renormalised over the taps kept as before. Three tiers (K/3, 2K/3) measured 4 % slower, one per
// Gaussian 17 % slower (each loop's own overhead on llvmpipe) and slower to compile.
//
// rejected: the share of the widest Gaussian's weight that fell on another surface (the pixel's own
// light stood in for it), in this pass and, averaged with the same weights, in the horizontal
// pass at the taps: 1 - (1 - this pass's) (1 - the horizontal pass's). Where it is large the
// blurred light jumps with the pixel's own light from one pixel to the next (beside a crease the
// hidden side continues with each pixel's own light), and the grain filter backs off.
void ssss_blur(ivec2 p, int pass_index, out vec3 result[MAX_GAUSSIANS], out bool wide[MAX_GAUSSIANS],
               out float rejected) {
    ivec2 size = textureSize(uIrradiance, 0);
    float cz;  // the pixel's view depth, mm
    vec3 np;
    vec3 centre[MAX_GAUSSIANS];  // the pixel's own light: what a tap on another surface brings
    float centre_rejected;
    ssss_fetch(p, true, 0, cz, np, centre, centre_rejected);
    SsssKernel K = ssss_kernel(cz, p, pass_index, max(size.x, size.y));
    // the widest Gaussian (its weight's rejected share): the last, the profile's variances increase
    // (dermis.profiles.SumOfGaussians) and ssss compiles for exactly its K: a constant index
    const int kw = MAX_GAUSSIANS - 1;
    rejected = 0.0;
    vec3 pp = ssss_view_position_mm(p, size, cz);
    SsssSums S;
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        S.sum[k] = vec3(0.0);
        S.wsum[k] = 0.0;
        S.own[k] = 0.0;
    }
    S.r_sum = 0.0;
    float log2_end = log2(float(K.last_px + 1));
    int next = 1;  // the next cell's first pixel
    int j = 0;
#if SSSS_NARROW > 0
    for (; j < SSSS_TAPS; ++j) {
        int start = next;
        if (start > K.narrow_reach_px) break;
        next = min(ssss_cell_start(j + 1, K.last_px, log2_end), K.last_px + 1);
        ssss_cell(0, j, start, next - start, p, K, cz, pp, np, size, S);
    }
#endif
    for (; j < SSSS_TAPS; ++j) {
        int start = next;
        if (start > K.last_px) break;
        next = min(ssss_cell_start(j + 1, K.last_px, log2_end), K.last_px + 1);
        ssss_cell(SSSS_NARROW, j, start, next - start, p, K, cz, pp, np, size, S);
    }
    float own_measure = ssss_measure(np);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        wide[k] = K.wide[k];
        float w = (1.0 + S.own[k]) * own_measure;  // exp(0): the pixel itself, and the rejected taps
        result[k] = (S.sum[k] + w * centre[k]) / max(S.wsum[k] + w, 1e-20);
        if (k == kw) {
            float total = max(S.wsum[k] + w, 1e-20);
            rejected = 1.0 - (1.0 - S.own[k] * own_measure / total) * (1.0 - (S.r_sum + w * centre_rejected) / total);
        }
    }
}
