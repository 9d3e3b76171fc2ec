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
// Reach: each Gaussian is followed out to where it falls below 1e-3 of its peak,
// sqrt(2 ln 1000) = 3.717 sigma (so the whole profile is covered to below 1e-3 of its own peak).
// Taps: each tap's weight is the 1-D Gaussian integrated over the tap's bin (erf), so each output
// pixel holds the light landing on its footprint, an impulse reproduces sum_k w_k G(v_k)
// integrated over pixels (tests/test_ssss.py), and Gaussians narrower than a pixel stay exact.
// A Gaussian whose reach fits in uMaxTaps pixels is sampled at every pixel (shared taps). A wider
// one gets its own step of s = ceil(reach / uMaxTaps) pixels, bins s pixels wide, and a per-pixel
// offset o in [0, s) of its tap grid (taps at o + j s): a fixed grid sees only every s-th pixel,
// which turned an impulse into +-10-20 % rings; with the offset drawn per pixel (a hash, so the
// image is stable from frame to frame) every pixel is covered with probability 1/s and weight
// about s g(x), so the blur is exact in expectation and the rings become fine noise that smooth
// irradiance averages away (Jimenez et al. 2015 jitter/rotate their kernels per pixel for the
// same reason). Weights are renormalised over the taps used (inside the frame).
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
// Tissue paths (as dermis.reference's paths = "tissue", TISSUE_TAU in techniques/shared.py): a tap q is skipped
// where the straight segment between the two surface points leaves either of them into the AIR,
// more than asin(uTissueTau) above its tangent plane: u.N_p > tau or -u.N_q > tau (u the unit
// offset from p to q, N the geometric normals of the pixels, view space). Across a crease (closed
// eyelids, lips, a nostril's rim) the two sides lie a pixel apart on screen and at about the same
// depth, so depth alone let the lit lids' light into the dark crease between them: a thin
// saturated orange line along both eyelid creases, where tsd (whose texture-space neighbours are
// the crease's own walls) and the reference show a dark line. Smooth convex skin keeps every tap
// (its neighbours lie below the tangent plane); concave skin of radius R keeps those within ~R/2.
// A skipped tap brings the pixel's own light (above). Keeping its weight with NO light (the
// crease's hidden walls taken as dark) was tried: the wide red Gaussians lost the most weight,
// and cyan lines appeared along every crease (nose wings, eye sockets).
#include "common/profile.glsl"

uniform sampler2D uIrradiance;          // pass 1: rgb pre-scatter irradiance, a = view depth mm (0: none)
uniform float uPixelsPerMmAtUnitDepth;  // along this pass's axis
uniform ivec2 uDirection;               // (1, 0) horizontal, (0, 1) vertical
uniform int uMaxTaps;                   // taps per side at most
uniform float uDepthCutoffMm;           // taps whose depth differs more are another surface
uniform float uFollowSurface;           // 1: weigh taps by the depth difference; 0: ignore depth (tests)
uniform sampler2D uViewNormal;          // pass 1: the geometric normal in view space (0: none)
uniform vec2 uPixelsPerMmXY;            // uPixelsPerMmAtUnitDepth along x and y: view-space offsets
uniform float uTissueTau;               // sin of the largest angle above the tangent plane; > 1: off
uniform float uSurfaceMeasure;          // 1: weigh taps by their surface per pixel (below); 0: off

const float SSSS_REACH_SIGMAS = 3.7169;  // sqrt(2 ln 1000): a Gaussian at 1e-3 of its peak

struct SsssKernel {
    float ppm;                           // pixels per mm at this pixel's depth
    int taps;                            // shared taps per side (Gaussians with step 1)
    float inv_sqrt2_sigma[MAX_GAUSSIANS]; // 1 / (sqrt(2) sigma_k), 1/px
    float inv_2var[MAX_GAUSSIANS];       // 1 / (2 v_k ppm^2), 1/px^2
    float reach_px[MAX_GAUSSIANS];       // 3.717 sigma_k + half a pixel (-1: unused, or a wide Gaussian)
    int wide_step_px[MAX_GAUSSIANS];     // 0: shared taps; s > 1: own jittered taps s pixels apart
    int wide_offset_px[MAX_GAUSSIANS];   // o in [0, s): this pixel's offset of its tap grid
    int wide_taps[MAX_GAUSSIANS];        // its taps per side
};

// An integer hash (Wang 1997 / Jenkins' 32-bit mix) -> [0, 1): per-pixel, per-Gaussian, per-pass.
float ssss_hash01(ivec2 p, int k, int pass_index) {
    uint h = uint(p.x) * 1973u + uint(p.y) * 9277u + uint(k) * 26699u + uint(pass_index) * 104729u + 1u;
    h = (h ^ 61u) ^ (h >> 16u);
    h *= 9u;
    h ^= h >> 4u;
    h *= 0x27d4eb2du;
    h ^= h >> 15u;
    return float(h >> 8u) / 16777216.0;
}

// erfc(x) for x >= 0, Abramowitz & Stegun 1964, 7.1.26 (|error of erf| < 1.5e-7), kept as the
// small number it is: a bin far out in a Gaussian's tail is the DIFFERENCE of two erfc values, and
// as 1 - erfc in float32 it cancelled to nothing or to twice its value (the impulse's tail beyond
// 3 sigma came out 1.2-2.7x the Gaussian's).
float ssss_erfc_positive(float x) {
    float t = 1.0 / (1.0 + 0.3275911 * x);
    return (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t * exp(-x * x);
}

float ssss_erf(float x) {
    return sign(x) * (1.0 - ssss_erfc_positive(abs(x)));
}

// integral over [low, high] (pixels) of the unit 1-D Gaussian of 1 / (sqrt 2 sigma) = inv.
float ssss_bin_weight(float low, float high, float inv) {
    float a = low * inv, b = high * inv;
    if (a >= 0.0) return 0.5 * (ssss_erfc_positive(a) - ssss_erfc_positive(b));
    if (b <= 0.0) return 0.5 * (ssss_erfc_positive(-b) - ssss_erfc_positive(-a));
    return 0.5 * (ssss_erf(b) - ssss_erf(a));
}

// The kernel at a pixel p whose view depth is depth_mm; pass_index 0 horizontal, 1 vertical.
SsssKernel ssss_kernel(float depth_mm, ivec2 p, int pass_index) {
    SsssKernel K;
    K.ppm = uPixelsPerMmAtUnitDepth / depth_mm;
    float shared_reach = 0.0;
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        float sigma_px = max(sqrt(uVariances[k]) * K.ppm, 1e-4);
        float reach = SSSS_REACH_SIGMAS * sigma_px + 0.5;
        K.inv_sqrt2_sigma[k] = 0.70710678 / sigma_px;
        K.inv_2var[k] = 0.5 / (sigma_px * sigma_px);
        K.wide_step_px[k] = 0;
        K.wide_offset_px[k] = 0;
        K.wide_taps[k] = 0;
        K.reach_px[k] = -1.0;
        if (k >= uGaussianCount) continue;
        if (reach <= float(uMaxTaps)) {
            K.reach_px[k] = reach;
            shared_reach = max(shared_reach, reach);
        } else {
            int s = int(ceil(reach / float(uMaxTaps)));
            K.wide_step_px[k] = s;
            K.wide_offset_px[k] = min(int(ssss_hash01(p, k, pass_index) * float(s)), s - 1);
            K.wide_taps[k] = int(ceil(reach / float(s))) + 1;
        }
    }
    K.taps = min(int(floor(shared_reach)), uMaxTaps);
    return K;
}

// Weight of a wide Gaussian's tap at signed offset d pixels: its bin [d - s/2, d + s/2].
float ssss_wide_weight(SsssKernel K, int k, int d) {
    float half_step = 0.5 * float(K.wide_step_px[k]);
    float low = float(d) - half_step, high = float(d) + half_step;
    float reach = SSSS_REACH_SIGMAS * 0.70710678 / K.inv_sqrt2_sigma[k] + half_step;
    if (high < -reach || low > reach) return 0.0;
    return ssss_bin_weight(low, high, K.inv_sqrt2_sigma[k]);
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
    vec2 c = (vec2(p) + 0.5 - 0.5 * vec2(size)) * z_mm / uPixelsPerMmXY;
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
    if (uFollowSurface == 0.0 || uSurfaceMeasure == 0.0) return 1.0;
    float na = dot(n.xy, vec2(uDirection));
    return min(sqrt(na * na + n.z * n.z) / max(abs(n.z), 1e-6), SSSS_MAX_MEASURE);
}

// False where the straight path from the pixel's surface point (view space, mm, with its normal
// np) to pixel q's (normal nq) crosses air (above).
bool ssss_tissue_path(vec3 pp, vec3 np, ivec2 q, vec3 nq, float zq, ivec2 size) {
    if (uTissueTau > 1.0) return true;
    vec3 d = ssss_view_position_mm(q, size, zq) - pp;
    float len = length(d);
    if (len <= 0.0) return true;
    vec3 u = d / len;
    return dot(u, np) <= uTissueTau && -dot(u, nq) <= uTissueTau;
}

// Pixel q's normal, fetched only when the tissue-path test or the surface measure reads it (they
// return before reading it otherwise: tissue_paths or follow_surface off, surface_measure off).
vec3 ssss_tap_normal(ivec2 q) {
    bool needed = uTissueTau <= 1.0 || (uFollowSurface != 0.0 && uSurfaceMeasure != 0.0);
    return needed ? texelFetch(uViewNormal, q, 0).xyz : vec3(0.0, 0.0, 1.0);
}

// Gaussian k's light at pixel q whose irradiance texel is ``tap``: defined by each pass (the
// horizontal pass: tap.rgb for every k; the vertical one: the horizontal pass's k-th image).
vec3 ssss_tap_light(int k, ivec2 q, vec4 tap);

// The 1-D blur along uDirection at pixel p, per Gaussian: out[k] = sum_taps w E_k / sum_taps w
// (pass_index 0 horizontal, 1 vertical), for a pixel on the skin (depth > 0).
// Written so that a GPU compiler keeps everything in registers: every loop over the Gaussians has
// a constant trip count (MAX_GAUSSIANS = the profile's K) and no loop inside, so it unrolls and
// each array is indexed by constants (a dynamic index sends the arrays to local memory: the
// first version looped over the wide Gaussians' own taps INSIDE a loop over k). Per tap and
// Gaussian there is one erfc (each bin's upper edge is the next bin's lower edge, kept), and
// the pixel's own position and normal are fetched once.
void ssss_blur(ivec2 p, int pass_index, out vec3 result[MAX_GAUSSIANS]) {
    ivec2 size = textureSize(uIrradiance, 0);
    vec4 c = texelFetch(uIrradiance, p, 0);
    SsssKernel K = ssss_kernel(c.a, p, pass_index);
    vec3 pp = ssss_view_position_mm(p, size, c.a);
    vec3 np = texelFetch(uViewNormal, p, 0).xyz;
    vec3 centre[MAX_GAUSSIANS];  // the pixel's own light: what a tap on another surface brings
    vec3 sum[MAX_GAUSSIANS];
    float wsum[MAX_GAUSSIANS];
    float own[MAX_GAUSSIANS];    // weight carried by the pixel's own light (its bin and rejected taps)
    float lower[MAX_GAUSSIANS];  // erfc at the lower edge of the next bin
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        centre[k] = ssss_tap_light(k, p, c);
        sum[k] = vec3(0.0);
        wsum[k] = 0.0;
        own[k] = ssss_erf(0.5 * K.inv_sqrt2_sigma[k]);  // the centre bin [-1/2, 1/2]
        lower[k] = ssss_erfc_positive(0.5 * K.inv_sqrt2_sigma[k]);
    }
    // Gaussians whose reach fits in uMaxTaps: taps at every pixel, shared
    for (int j = 1; j <= K.taps; ++j) {
        float wx[MAX_GAUSSIANS];  // the bin [j - 1/2, j + 1/2] of each Gaussian
        for (int k = 0; k < MAX_GAUSSIANS; ++k) {
            if (float(j) - 0.5 > K.reach_px[k]) { wx[k] = 0.0; continue; }  // also wide ones, k >= count
            float upper = ssss_erfc_positive((float(j) + 0.5) * K.inv_sqrt2_sigma[k]);
            wx[k] = 0.5 * (lower[k] - upper);
            lower[k] = upper;
        }
        for (int side = -1; side <= 1; side += 2) {
            ivec2 q = p + uDirection * (side * j);
            if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
            vec4 t = texelFetch(uIrradiance, q, 0);
            vec3 nq = ssss_tap_normal(q);
            float dz_px = ssss_tap_dz_px(K, c.a, t.a);
            if (dz_px < 0.0 || !ssss_tissue_path(pp, np, q, nq, t.a, size)) {
                for (int k = 0; k < MAX_GAUSSIANS; ++k) own[k] += wx[k];  // another surface
                continue;
            }
            float dz2 = dz_px * dz_px;
            float measure = ssss_measure(nq);
            for (int k = 0; k < MAX_GAUSSIANS; ++k) {
                if (wx[k] <= 0.0) continue;
                float u = dz2 * K.inv_2var[k];
                float w = wx[k] * measure * (u < 2e-3 ? 1.0 - u : exp(-u));  // the depth factor (above)
                sum[k] += w * ssss_tap_light(k, q, t);
                wsum[k] += w;
            }
        }
    }
    // Gaussians wider than uMaxTaps pixels: their own jittered taps, s pixels apart (above)
    int wide_taps = 0;
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (K.wide_step_px[k] == 0) continue;
        sum[k] = vec3(0.0);
        wsum[k] = 0.0;
        own[k] = 0.0;
        wide_taps = max(wide_taps, K.wide_taps[k]);
    }
    for (int j = -wide_taps; j <= wide_taps; ++j) {
        for (int k = 0; k < MAX_GAUSSIANS; ++k) {
            if (K.wide_step_px[k] == 0 || abs(j) > K.wide_taps[k]) continue;
            int d = j * K.wide_step_px[k] + K.wide_offset_px[k];
            float w = ssss_wide_weight(K, k, d);
            if (w <= 0.0) continue;
            ivec2 q = p + uDirection * d;
            if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
            vec4 t = texelFetch(uIrradiance, q, 0);
            vec3 nq = ssss_tap_normal(q);
            float dz_px = ssss_tap_dz_px(K, c.a, t.a);
            if (dz_px < 0.0 || !ssss_tissue_path(pp, np, q, nq, t.a, size)) {
                own[k] += w;  // another surface
                continue;
            }
            float u = dz_px * dz_px * K.inv_2var[k];
            w *= ssss_measure(nq) * (u < 2e-3 ? 1.0 - u : exp(-u));
            sum[k] += w * ssss_tap_light(k, q, t);
            wsum[k] += w;
        }
    }
    float own_measure = ssss_measure(np);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        float w = own[k] * own_measure;
        result[k] = (sum[k] + w * centre[k]) / max(wsum[k] + w, 1e-20);
    }
}
