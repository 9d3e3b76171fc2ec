// Separable SSS, pass 3: the vertical 1-D blur of each Gaussian's horizontal result, summed with
// the profile's weights (normalised per channel): the scattered, pre-albedo diffuse light
//   rgb = sum_k w_k (g_k(y) * (g_k(x) * E)),  a = view depth in mm (copied, for the final pass).
#include "ssss/kernel.glsl"

uniform sampler2D uGaussian[MAX_GAUSSIANS];  // the horizontal pass's outputs
out vec4 f_scattered;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 size = textureSize(uIrradiance, 0);
    float depth = texelFetch(uIrradiance, p, 0).a;
    if (depth <= 0.0) {
        f_scattered = vec4(0.0);
        return;
    }
    SsssKernel K = ssss_kernel(depth, p, 1);
    vec3 sum[MAX_GAUSSIANS];
    float wsum[MAX_GAUSSIANS];
    float edge[MAX_GAUSSIANS];
    vec3 centre[MAX_GAUSSIANS];  // this pixel's horizontal results: what a rejected tap contributes
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        edge[k] = ssss_centre_weight(K, k);
        wsum[k] = edge[k];
        centre[k] = k < uGaussianCount ? texelFetch(uGaussian[k], p, 0).rgb : vec3(0.0);
        sum[k] = edge[k] * centre[k];
    }
    for (int j = 1; j <= K.taps; ++j) {
        float x = float(j * K.step_px);
        float wx[MAX_GAUSSIANS];
        for (int k = 0; k < MAX_GAUSSIANS; ++k) {
            if (x - 0.5 * float(K.step_px) > K.reach_px[k]) { wx[k] = 0.0; continue; }
            wx[k] = ssss_bin_weight(x - 0.5 * float(K.step_px), x + 0.5 * float(K.step_px), K.inv_sqrt2_sigma[k]);
        }
        for (int side = -1; side <= 1; side += 2) {
            ivec2 q = p + uDirection * (side * j * K.step_px);
            if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
            float zq = texelFetch(uIrradiance, q, 0).a;
            float dz_px = ssss_tap_dz_px(K, depth, zq);
            if (dz_px < 0.0 || !ssss_tissue_path(p, depth, q, zq, size)) {
                for (int k = 0; k < MAX_GAUSSIANS; ++k) {  // another surface: the pixel's own light
                    sum[k] += wx[k] * centre[k];
                    wsum[k] += wx[k];
                }
                continue;
            }
            for (int k = 0; k < MAX_GAUSSIANS; ++k) {
                if (wx[k] <= 0.0) continue;
                float w = wx[k] * ssss_depth_factor(K, k, dz_px);
                sum[k] += w * texelFetch(uGaussian[k], q, 0).rgb;
                wsum[k] += w;
            }
        }
    }
    // Gaussians wider than uMaxTaps pixels: their own jittered taps (ssss/kernel.glsl)
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (K.wide_step_px[k] == 0) continue;
        sum[k] = vec3(0.0);
        wsum[k] = 0.0;
        for (int j = -K.wide_taps[k]; j <= K.wide_taps[k]; ++j) {
            int d = ssss_wide_offset(K, k, j);
            float w = ssss_wide_weight(K, k, d);
            if (w <= 0.0) continue;
            ivec2 q = p + uDirection * d;
            if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
            float zq = texelFetch(uIrradiance, q, 0).a;
            float dz_px = ssss_tap_dz_px(K, depth, zq);
            if (dz_px < 0.0 || !ssss_tissue_path(p, depth, q, zq, size)) {
                sum[k] += w * centre[k];  // another surface: the pixel's own light
                wsum[k] += w;
                continue;
            }
            w *= ssss_depth_factor(K, k, dz_px);
            sum[k] += w * texelFetch(uGaussian[k], q, 0).rgb;
            wsum[k] += w;
        }
    }
    vec3 scattered = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        scattered += uWeights[k] * sum[k] / max(wsum[k], 1e-20);
    }
    f_scattered = vec4(scattered, depth);
}
