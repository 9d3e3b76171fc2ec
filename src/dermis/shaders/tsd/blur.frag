// One direction (U or V) of one chained Gaussian blur in texture space (d'Eon & Luebke 2007,
// 14.4.2-14.4.3): I_k = I_(k-1) * G(v_k - v_(k-1)), separable, tap spacing from the stretch map.
// Taps sit at integer multiples of a step of >= 1 texel, each weighted by a Gaussian integrated
// over its bin (d'Eon's 7 weights are this with step = sigma). Binning adds step^2 / 12 to the
// kernel's variance (Sheppard's correction), so the bins integrate a Gaussian of variance
// sigma^2 - step^2 / 12: the discrete kernel then has the intended variance, and a chain of K
// blurs adds up to v_K exactly instead of v_K + K / 12 texel^2. The chain's first step keeps one
// bin (uFootprint = 1): each output texel then holds the light landing on its footprint, i.e. the
// profile integrated over the texel, exactly once.
// Seams: colour is a NORMALISED convolution over covered texels (alpha = coverage), so empty
// gutters never darken an island's edge; alpha returns the blurred coverage; where nothing is
// covered the (dilated) input colour passes through.
uniform sampler2D uSource;    // rgb colour, a = coverage
uniform sampler2D uStretch;   // xy = texels per mm along u, v at level 0
uniform vec2 uDirection;      // (1, 0) = U pass, (0, 1) = V pass
uniform float uSigmaMm;       // this step's standard deviation, mm
uniform float uLevelScale;    // texels of this level per level-0 texel (2^-level)
uniform float uFootprint;     // 1: integrate over the receiving texel (first step), 0: exact variance
in vec2 v_uv;
out vec4 f_color;

// Abramowitz & Stegun 1964, 7.1.26: |error| < 1.5e-7.
float erf_as(float x) {
    float s = sign(x);
    x = abs(x);
    float t = 1.0 / (1.0 + 0.3275911 * x);
    float y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t * exp(-x * x);
    return s * y;
}

// TAPS (taps per side, a compile-time constant: the loop unrolls, which matters on CPU
// rasterisers where a per-pixel loop bound costs more than the taps) is chosen per pass by tsd.py
// from the widest sigma in the texture. Taps sit on texel centres (integer spacing) and are
// fetched without filtering. Adjacent bins share an edge, so each tap costs one erf.
#ifndef TAPS
#define TAPS 12
#endif

void main() {
    ivec2 isize = textureSize(uSource, 0);
    ivec2 ip = ivec2(gl_FragCoord.xy);
    vec4 center = texelFetch(uSource, ip, 0);
    vec2 st = texelFetch(uStretch, min(ip, textureSize(uStretch, 0) - 1), 0).xy;
    float sigma = uSigmaMm * dot(st, uDirection) * uLevelScale;  // texels of this level
    if (sigma < 0.05) { f_color = center; return; }
    float step_ = max(1.0, ceil(3.0 * sigma / float(TAPS)));
    int n = int(min(ceil(3.0 * sigma / step_ - 0.001), float(TAPS)));
    ivec2 dir = ivec2(uDirection) * int(step_);
    ivec2 imax = isize - 1;
    float sb = sqrt(max(sigma * sigma - (1.0 - uFootprint) * step_ * step_ / 12.0, 0.0025));  // Sheppard
    float inv = 1.0 / (sb * 1.41421356);
    float edge = erf_as(0.5 * step_ * inv);  // erf at the upper edge of the previous bin
    float w0 = edge;                          // bin 0: [-step/2, step/2]
    vec3 sum = center.rgb * center.a * w0;
    float sum_a = center.a * w0;
    float sum_w = w0;
    for (int j = 1; j <= TAPS; ++j) {
        float e = erf_as((float(j) + 0.5) * step_ * inv);
        float w = 0.5 * (e - edge);
        edge = e;
        if (j == n) w += 0.5 * (1.0 - e);  // fold the tail in
        w = j <= n ? w : 0.0;
        vec4 a = texelFetch(uSource, clamp(ip + dir * j, ivec2(0), imax), 0);
        vec4 b = texelFetch(uSource, clamp(ip - dir * j, ivec2(0), imax), 0);
        sum += w * (a.rgb * a.a + b.rgb * b.a);
        sum_a += w * (a.a + b.a);
        sum_w += 2.0 * w;
    }
    vec3 rgb = sum_a > 1e-6 ? sum / sum_a : center.rgb;
    f_color = vec4(rgb, sum_a / sum_w);
}
