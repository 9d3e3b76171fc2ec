// One direction (U or V) of one chained Gaussian blur in texture space (d'Eon & Luebke 2007,
// 14.4.2-14.4.3): I_k = I_(k-1) * G(v_k - v_(k-1)), separable, tap spacing from the stretch map.
// The chain's first step keeps one bin per texel (FOOTPRINT): each output texel then holds the
// light landing on its footprint, i.e. the profile integrated over the texel, exactly once.
//
// Weights: the first step (FOOTPRINT) integrates the Gaussian over each tap's bin with erf, as
// the profile integrated over the receiving texel must be exact there even for sub-texel sigmas.
// Every later step only has to ADD its variance sigma^2 exactly (the chain's variances sum), so
// its taps are the sampled Gaussian exp(-x^2 / 2 sigma^2), by recurrence (w_j = w_(j-1) q_j,
// q_j = q_(j-1) g^2: two multiplies per tap instead of an erf, which costs as much as a fetch on
// a CPU rasteriser), followed by a correction that makes the discrete kernel's variance exactly
// sigma^2: weight delta = W (sigma^2 - V) / 2 (x_m^2 - sigma^2) added to the taps +-x_m (x_m about
// 2 sigma), where W and V are the kernel's weight and variance so far. For sigma < ~0.7 texel
// the sampled Gaussian alone falls short of sigma^2 (at 0.3 texel it is [0.004, 0.99, 0.004]);
// the correction gives the 3-tap kernel of exactly that variance. Taps sit on texel centres at a
// step of >= 1 texel (wider kernels space their taps; point samples need no Sheppard term).
//
// Non-orthogonal layouts: with P_u, P_v the surface vectors of one texel along u and v (cos c
// between them), a U pass of sigma / |P_u| and a V pass of sigma / |P_v| texels give the kernel
// sigma^2 (e_u e_u^T + e_v e_v^T) on the surface, whose variance across an edge runs from
// sigma^2 (1 - |c|) to sigma^2 (1 + |c|): a red rim up to 26% too bright 2 mm into a shadow at
// c = 0.5 (tests/test_shadow_edge_rim.py). So the V pass steps along w = (k, 1) texels,
// k = -c |P_v| / |P_u|, whose surface vector P_v + k P_u is orthogonal to P_u and |P_v| sqrt(1 - c^2)
// long: U and V are then orthogonal on the surface and the kernel is sigma^2 I. Taps at fractional
// u are rounded to the nearest texel: one fetch, and a tap moved by d = u - round(u) spreads the
// kernel by its weighted d^2 along u (at most 1/4 texel^2, 1/12 on average; a linear read between the
// two texels would cost two fetches and spread t (1 - t), twice that), which the U pass (drawn
// first, told the V pass's sigma) takes off its own variance.
//
// Premultiplied data (rgb = colour x coverage, a = coverage): the normalised convolution over
// covered texels that hides seams (colour = sum w a c / sum w a) is then a plain linear filter of
// (rgb, a), normalised only where it is read (tsd/gaussians.glsl). Gutters hold the nearest
// island's colour at a small coverage (tsd/dilate.frag): they never darken an island's edge and
// keep a colour where no island reaches.
uniform sampler2D uSource;    // premultiplied rgb, a = coverage
uniform sampler2D uStretch;   // xy = texels per mm along u, v at level 0; z = cos(angle of u, v on the surface)
uniform vec2 uDirection;      // (1, 0) = U pass, (0, 1) = V pass
uniform float uSigmaMm;       // this step's standard deviation, mm
uniform float uSigmaOtherMm;  // U pass: the V pass's sigma (mm), for the variance its skewed reads add along u
uniform float uLevelScale;    // texels of this level per level-0 texel (2^-level)
out vec4 f_color;

// Abramowitz & Stegun 1964, 7.1.26: |error| < 1.5e-7.
float erf_as(float x) {
    float s = sign(x);
    x = abs(x);
    float t = 1.0 / (1.0 + 0.3275911 * x);
    float y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t * exp(-x * x);
    return s * y;
}

// TAPS (taps per side, a compile-time constant: the loops unroll, which matters on CPU rasterisers
// where a per-pixel loop bound costs more than the taps) is chosen per pass by tsd.py from the
// widest sigma that 75% of the layout has (TAP_STRETCH_PERCENTILE).
#ifndef TAPS
#define TAPS 4
#endif
#ifndef REACH
#define REACH 3.0
#endif

// Texel reads: uSource and uStretch are bound with a NEAREST, CLAMP_TO_EDGE sampler object (tsd.py,
// _pass(nearest=True)) and read at texel centres, which gives the texel clamp(p, 0, size - 1) exactly,
// as texelFetch of the clamped texel did, bit for bit; on llvmpipe a sampled read costs ~0.3-0.4 ms
// less per tap over 1024^2 RGBA16F texels than texelFetch (its bounds checks; round 23, chain23).
#include "common/texel.glsl"

// the source at ip + j (skew, 1) along V, u rounded to the nearest texel (one fetch; the rounding's
// spread along u is taken off by the U pass), ip + j (1, 0) along U
vec4 tap(ivec2 ip, ivec2 dir, float skew, int j) {
    ivec2 o = dir * j;
    o.x += int(floor(skew * float(j) + 0.5));  // the same rounding as the U pass's account of it
    return TEXEL(uSource, ip + o);
}

void main() {
    ivec2 ip = ivec2(gl_FragCoord.xy);
    vec4 center = TEXEL(uSource, ip);
    vec3 st = TEXEL(uStretch, ip).xyz;
    // V: along the direction orthogonal to u on the surface (see above); |c| <= 0.95 keeps it finite
    float cz = clamp(st.z, -0.95, 0.95);
    float c = uDirection.y > 0.5 ? cz : 0.0;
    float skew = -c * st.x / max(st.y, 1e-9);  // texels of u per texel of v
    float sigma = uSigmaMm * dot(st.xy, uDirection) * uLevelScale / sqrt(1.0 - c * c);  // texels of this level
    if (uDirection.x > 0.5 && cz != 0.0) {
        // the V pass's taps (its sampled-Gaussian weights) and the weighted d^2 of their rounding along u
        float sv = uSigmaOtherMm * st.y * uLevelScale / sqrt(1.0 - cz * cz);
        if (sv >= 0.02) {
            float sv_step = max(1.0, ceil(REACH * sv / float(TAPS)));
            float k = -cz * st.x / max(st.y, 1e-9) * sv_step;
            float Wv = 1.0, Ev = 0.0;
            float gv = exp(-0.5 * sv_step * sv_step / (sv * sv)), gv2 = gv * gv, wv = 1.0, qv = gv;
            for (int j = 1; j <= TAPS; ++j) {
                wv *= qv;  // exp(-x_j^2 / 2 sv^2) by recurrence, as below
                qv *= gv2;
                float d = k * float(j) - floor(k * float(j) + 0.5);
                Wv += 2.0 * wv;
                Ev += 2.0 * wv * d * d;
            }
            sigma = sqrt(max(sigma * sigma - Ev / Wv, 0.0));
        }
    }
    if (sigma < 0.02) { f_color = center; return; }
    float step_ = max(1.0, ceil(REACH * sigma / float(TAPS)));
    ivec2 dir = ivec2(uDirection) * int(step_);
    skew *= step_;  // per step of dir
#ifdef FOOTPRINT
    // bins of `step_` texels, the Gaussian integrated over each (Sheppard: bins of more than one
    // texel integrate sigma^2 - step^2 / 12 ... except the receiving texel's own, which is the point)
    int n = int(min(ceil(REACH * sigma / step_ - 0.001), float(TAPS)));
    float sb = step_ > 1.0 ? sqrt(max(sigma * sigma - (step_ * step_ - 1.0) / 12.0, 0.0025)) : sigma;
    float inv = 1.0 / (sb * 1.41421356);
    float edge = erf_as(0.5 * step_ * inv);
    vec4 sum = center * edge;
    for (int j = 1; j <= TAPS; ++j) {
        // the last tap's upper edge is never used (n <= TAPS: the tail folds into tap n)
        float e = j < TAPS ? erf_as((float(j) + 0.5) * step_ * inv) : 1.0;
        float w = j < n ? 0.5 * (e - edge) : (j == n ? 0.5 * (1.0 - edge) : 0.0);  // the tail folded in
        edge = e;
        sum += w * (tap(ip, dir, skew, j) + tap(ip, dir, skew, -j));
    }
    f_color = sum;
#else
    float var = sigma * sigma;  // texel^2 of this level
    float g = exp(-0.5 * step_ * step_ / var);
    float g2 = g * g;
    float w = 1.0, q = g;
    vec4 sum = center;
    float W = 1.0, M = 0.0;
    // the correction's taps: about 2 sigma out, at least the first, at most the last
    int m = int(clamp(floor(2.0 * sigma / step_ + 0.5), 1.0, float(TAPS)));
    vec4 outer = vec4(0.0);
    for (int j = 1; j <= TAPS; ++j) {
        w *= q;
        q *= g2;
        vec4 ab = tap(ip, dir, skew, j) + tap(ip, dir, skew, -j);
        float x = float(j) * step_;
        sum += w * ab;
        W += 2.0 * w;
        M += 2.0 * w * x * x;
        if (j == m) outer = ab;
    }
    float xm = float(m) * step_;
    // (M + 2 delta xm^2) / (W + 2 delta) = var: delta goes to both taps +-xm (round 3 had no 1/2 here:
    // its kernels were over-corrected by the residual, 0.9% of sigma^2 at 3 sigma, 2x at sub-texel sigmas)
    float delta = 0.5 * (var * W - M) / max(xm * xm - var, 1e-6);
    delta = max(delta, -0.5 * W);  // never a negative total
    f_color = (sum + delta * outer) / (W + 2.0 * delta);
#endif
}
