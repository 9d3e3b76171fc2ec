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
// Taps sit at multiples of an integer step (1 pixel unless 3 sigma of the widest Gaussian exceeds
// uMaxTaps pixels); each tap's weight is the 1-D Gaussian integrated over the tap's bin (erf), so
// each output pixel holds the light landing on its footprint, an impulse reproduces
// sum_k w_k G(v_k) integrated over pixels (tests/test_ssss.py), and Gaussians narrower than a
// pixel stay exact. Each Gaussian stops at 3 sigma; weights are renormalised over the taps used.
//
// Following the surface (Jimenez et al. 2009, sec. 4; 2015, SSSS_FOLLOW_SURFACE): a tap whose
// depth differs by dz mm lies that much further away on the surface, so its weight also carries
// the Gaussian's factor exp(-dz^2 / 2 v_k) (G(v, sqrt(x^2 + dz^2)) = G(v, x) exp(-dz^2 / 2v));
// taps with |dz| > uDepthCutoffMm (a silhouette) and taps off the mesh are rejected outright.
// Renormalisation keeps the energy: light neither bleeds across silhouettes nor leaks into the
// background, and slanted surfaces get narrower screen-space kernels, as they should.
#include "common/profile.glsl"

uniform sampler2D uIrradiance;          // pass 1: rgb pre-scatter irradiance, a = view depth mm (0: none)
uniform float uPixelsPerMmAtUnitDepth;  // along this pass's axis
uniform ivec2 uDirection;               // (1, 0) horizontal, (0, 1) vertical
uniform int uMaxTaps;                   // taps per side at most
uniform float uDepthCutoffMm;           // taps whose depth differs more are another surface
uniform float uFollowSurface;           // 1: weigh taps by the depth difference; 0: ignore depth (tests)

struct SsssKernel {
    float ppm;                           // pixels per mm at this pixel's depth
    int step_px;                         // tap spacing, pixels
    int taps;                            // taps per side
    float inv_sqrt2_sigma[MAX_GAUSSIANS]; // 1 / (sqrt(2) sigma_k), 1/px
    float inv_2var[MAX_GAUSSIANS];       // 1 / (2 v_k ppm^2), 1/px^2
    float reach_px[MAX_GAUSSIANS];       // 3 sigma_k + half a step, pixels (-1: unused)
};

// Abramowitz & Stegun 1964, 7.1.26: |error| < 1.5e-7.
float ssss_erf(float x) {
    float s = sign(x);
    x = abs(x);
    float t = 1.0 / (1.0 + 0.3275911 * x);
    float y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t * exp(-x * x);
    return s * y;
}

SsssKernel ssss_kernel(float depth_mm) {
    SsssKernel K;
    K.ppm = uPixelsPerMmAtUnitDepth / depth_mm;
    float widest = 3.0 * sqrt(uVariances[max(uGaussianCount - 1, 0)]) * K.ppm;
    K.step_px = max(1, int(ceil(widest / float(uMaxTaps) - 1e-4)));
    float step = float(K.step_px);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        float sigma_px = max(sqrt(uVariances[k]) * K.ppm, 1e-4);
        K.inv_sqrt2_sigma[k] = 0.70710678 / sigma_px;
        K.inv_2var[k] = 0.5 / (sigma_px * sigma_px);
        K.reach_px[k] = k < uGaussianCount ? 3.0 * sigma_px + 0.5 * step : -1.0;
    }
    K.taps = min(int(floor(K.reach_px[max(uGaussianCount - 1, 0)] / step)), uMaxTaps);
    return K;
}

// Centre bin of Gaussian k: integral over [-step/2, step/2].
float ssss_centre_weight(SsssKernel K, int k) {
    return ssss_erf(0.5 * float(K.step_px) * K.inv_sqrt2_sigma[k]);
}

// Depth factor of a tap for Gaussian k: exp(-dz^2 / 2 v_k); dz_px = depth difference in pixels.
// Below an exponent of 2e-3, 1 - u is exact to 2e-6 and skips the exp (a third of the blurs' time
// on llvmpipe: most taps of the wide Gaussians barely change depth).
float ssss_depth_factor(SsssKernel K, int k, float dz_px) {
    float u = dz_px * dz_px * K.inv_2var[k];
    return u < 2e-3 ? 1.0 - u : exp(-u);
}

// Depth difference of a tap in pixels at this depth, or -1 to reject the tap.
float ssss_tap_dz_px(SsssKernel K, float depth_mm, float tap_depth_mm) {
    if (tap_depth_mm <= 0.0) return -1.0;  // no surface there
    float dz = abs(tap_depth_mm - depth_mm) * uFollowSurface;
    if (dz > uDepthCutoffMm) return -1.0;
    return dz * K.ppm;
}
