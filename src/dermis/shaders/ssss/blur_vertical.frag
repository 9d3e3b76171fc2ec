// Separable SSS, pass 3: the vertical 1-D blur of each Gaussian's horizontal result, summed with
// the profile's weights (normalised per channel): the scattered, pre-albedo diffuse light
//   rgb = sum_k w_k (g_k(y) * (g_k(x) * E)),  a = view depth in mm (copied, for the final pass).
// With the grain filter (SSSS_GRAIN_FILTER, ssss/kernel.glsl) the Gaussians blurred for it are
// summed apart into f_wide (rgb; a = their bit mask, bit k for Gaussian k, plus the rejected
// share, ssss/kernel.glsl, times 0.5: a = mask + rejected / 2), which
// ssss/grain_filter.frag convolves with the 3 x 3 binomial and adds to f_scattered's rgb.
#include "ssss/kernel.glsl"
#include "ssss/packing.glsl"

uniform usampler2D uPacked[SSSS_PACKED];  // the horizontal pass's results (ssss/packing.glsl), transposed:
                                          // pixel q at texel q.yx (ssss/blur_horizontal.frag says why)
layout(location = 0) out vec4 f_scattered;
#if SSSS_GRAIN_FILTER
layout(location = 1) out vec4 f_wide;
#endif

void ssss_fetch(ivec2 q, bool centre, const int first_k, out float depth_mm, out vec3 normal,
                out vec3 light[MAX_GAUSSIANS], out float rejected) {
    uvec4 texels[SSSS_PACKED];
    // only the texels of Gaussians first_k.. (a constant: the others are not fetched)
    int used = ssss_packed_texels(first_k);
    for (int t = 0; t < SSSS_PACKED; ++t) texels[t] = t < used ? TEXEL(uPacked[t], q.yx) : uvec4(0u);
    ssss_unpack(texels, depth_mm, normal, light, rejected);
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    float depth = TEXEL(uIrradiance, p).a;
    if (depth <= 0.0) {
        f_scattered = vec4(0.0);
#if SSSS_GRAIN_FILTER
        f_wide = vec4(0.0);
#endif
        return;
    }
    vec3 blurred[MAX_GAUSSIANS];
    bool wide[MAX_GAUSSIANS];
    float rejected;
    ssss_blur(p, 1, blurred, wide, rejected);
    vec3 scattered = vec3(0.0);
    vec3 scattered_wide = vec3(0.0);
    int mask = 0;
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        if (wide[k]) {
            scattered_wide += uWeights[k] * blurred[k];
            mask |= 1 << k;
        } else {
            scattered += uWeights[k] * blurred[k];
        }
    }
    f_scattered = vec4(scattered, depth);
#if SSSS_GRAIN_FILTER
    f_wide = vec4(scattered_wide, float(mask) + 0.5 * clamp(rejected, 0.0, 1.0));
#endif
}
