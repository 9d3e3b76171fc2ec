// The sum-of-Gaussians profile as uniforms: K <= MAX_GAUSSIANS blurred irradiance textures
// I_1..I_K and their weights, renormalised per channel so that sum_k w_k = 1 (d'Eon & Luebke 2007,
// 14.4.4: "the weights are normalised so that white light stays white").
#include "common/profile.glsl"
uniform sampler2D uBlur[MAX_GAUSSIANS];

vec3 diffuse_irradiance(vec2 uv) {
    vec3 E = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        E += uWeights[k] * texture(uBlur[k], uv).rgb;
    }
    return E;
}
