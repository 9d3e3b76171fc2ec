// Separable SSS, pass 2: the horizontal 1-D blur, one output per Gaussian of the profile
// (ssss/kernel.glsl): f_gaussian[k].rgb = sum_taps g_k E / sum_taps g_k.
#include "ssss/kernel.glsl"

layout(location = 0) out vec4 f_gaussian[MAX_GAUSSIANS];

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 size = textureSize(uIrradiance, 0);
    vec4 c = texelFetch(uIrradiance, p, 0);
    vec3 sum[MAX_GAUSSIANS];
    float wsum[MAX_GAUSSIANS];
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        sum[k] = c.rgb;
        wsum[k] = 1.0;
    }
    if (c.a > 0.0) {
        SsssKernel K = ssss_kernel(c.a, p, 0);
        float edge[MAX_GAUSSIANS];  // the centre bin's weight
        for (int k = 0; k < MAX_GAUSSIANS; ++k) {
            edge[k] = ssss_centre_weight(K, k);
            wsum[k] = edge[k];
            sum[k] = c.rgb * edge[k];
        }
        for (int j = 1; j <= K.taps; ++j) {
            float x = float(j * K.step_px);
            float wx[MAX_GAUSSIANS];
            for (int k = 0; k < MAX_GAUSSIANS; ++k) {
                if (x - 0.5 * float(K.step_px) > K.reach_px[k]) { wx[k] = 0.0; continue; }  // also k >= count
                wx[k] = ssss_bin_weight(x - 0.5 * float(K.step_px), x + 0.5 * float(K.step_px), K.inv_sqrt2_sigma[k]);
            }
            for (int side = -1; side <= 1; side += 2) {
                ivec2 q = p + uDirection * (side * j * K.step_px);
                if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) continue;
                vec4 t = texelFetch(uIrradiance, q, 0);
                float dz_px = ssss_tap_dz_px(K, c.a, t.a);
                if (dz_px < 0.0 || !ssss_tissue_path(p, c.a, q, t.a, size)) {
                    for (int k = 0; k < MAX_GAUSSIANS; ++k) {  // another surface: the pixel's own light
                        sum[k] += wx[k] * c.rgb;
                        wsum[k] += wx[k];
                    }
                    continue;
                }
                for (int k = 0; k < MAX_GAUSSIANS; ++k) {
                    if (wx[k] <= 0.0) continue;
                    float w = wx[k] * ssss_depth_factor(K, k, dz_px);
                    sum[k] += w * t.rgb;
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
                vec4 t = texelFetch(uIrradiance, q, 0);
                float dz_px = ssss_tap_dz_px(K, c.a, t.a);
                if (dz_px < 0.0 || !ssss_tissue_path(p, c.a, q, t.a, size)) {
                    sum[k] += w * c.rgb;  // another surface: the pixel's own light
                    wsum[k] += w;
                    continue;
                }
                w *= ssss_depth_factor(K, k, dz_px);
                sum[k] += w * t.rgb;
                wsum[k] += w;
            }
        }
    }
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        f_gaussian[k] = vec4(sum[k] / max(wsum[k], 1e-20), 1.0);
    }
}
