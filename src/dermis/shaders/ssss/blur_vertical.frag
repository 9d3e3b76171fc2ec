// Separable SSS, pass 3: the vertical 1-D blur of each Gaussian's horizontal result, summed with
// the profile's weights (normalised per channel): the scattered, pre-albedo diffuse light
//   rgb = sum_k w_k (g_k(y) * (g_k(x) * E)),  a = view depth in mm (copied, for the final pass).
#include "ssss/kernel.glsl"

uniform sampler2D uGaussian[MAX_GAUSSIANS];  // the horizontal pass's outputs
out vec4 f_scattered;

vec3 ssss_tap_light(int k, ivec2 q, vec4 tap) {
    return k < uGaussianCount ? texelFetch(uGaussian[k], q, 0).rgb : vec3(0.0);
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
