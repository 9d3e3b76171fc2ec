// The sum-of-Gaussians profile as uniforms: K <= MAX_GAUSSIANS blurred irradiance textures
// I_1..I_K and their weights, renormalised per channel so that sum_k w_k = 1 (d'Eon & Luebke 2007,
// 14.4.4: "the weights are normalised so that white light stays white").
#ifndef MAX_GAUSSIANS
#define MAX_GAUSSIANS 8
#endif
uniform int uGaussianCount;
uniform sampler2D uBlur[MAX_GAUSSIANS];
uniform vec3 uWeights[MAX_GAUSSIANS];
uniform float uVariances[MAX_GAUSSIANS];  // mm^2

vec3 diffuse_irradiance(vec2 uv) {
    vec3 E = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        E += uWeights[k] * texture(uBlur[k], uv).rgb;
    }
    return E;
}
