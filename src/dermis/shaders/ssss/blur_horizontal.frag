// Separable SSS, pass 2: the horizontal 1-D blur, one output per Gaussian of the profile
// (ssss/kernel.glsl): f_gaussian[k].rgb = sum_taps g_k E / sum_taps g_k.
#include "ssss/kernel.glsl"

layout(location = 0) out vec4 f_gaussian[MAX_GAUSSIANS];

vec3 ssss_tap_light(int k, ivec2 q, vec4 tap) {
    return tap.rgb;  // the pre-scatter light, the same for every Gaussian
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(uIrradiance, p, 0);
    vec3 blurred[MAX_GAUSSIANS];
    if (c.a > 0.0) {
        ssss_blur(p, 0, blurred);
    } else {
        for (int k = 0; k < MAX_GAUSSIANS; ++k) blurred[k] = c.rgb;
    }
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        f_gaussian[k] = vec4(blurred[k], 1.0);
    }
}
