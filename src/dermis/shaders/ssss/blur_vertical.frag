// Separable SSS, pass 3: the vertical 1-D blur of each Gaussian's horizontal result, summed with
// the profile's weights (normalised per channel): the scattered, pre-albedo diffuse light
//   rgb = sum_k w_k (g_k(y) * (g_k(x) * E)),  a = view depth in mm (copied, for the final pass).
#include "ssss/kernel.glsl"
#include "ssss/packing.glsl"

uniform usampler2D uPacked[SSSS_PACKED];  // the horizontal pass's results (ssss/packing.glsl)
out vec4 f_scattered;

void ssss_fetch(ivec2 q, bool centre, out float depth_mm, out vec3 normal, out vec3 light[MAX_GAUSSIANS]) {
    uvec4 texels[SSSS_PACKED];
    for (int t = 0; t < SSSS_PACKED; ++t) texels[t] = texelFetch(uPacked[t], q, 0);
    ssss_unpack(texels, depth_mm, normal, light);
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    float depth = texelFetch(uIrradiance, p, 0).a;
    if (depth <= 0.0) {
        f_scattered = vec4(0.0);
        return;
    }
    vec3 blurred[MAX_GAUSSIANS];
    ssss_blur(p, 1, blurred);
    vec3 scattered = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        scattered += uWeights[k] * blurred[k];
    }
    f_scattered = vec4(scattered, depth);
}
