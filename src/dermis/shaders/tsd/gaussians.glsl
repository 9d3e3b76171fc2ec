// The sum-of-Gaussians profile as uniforms: K <= MAX_GAUSSIANS blurred irradiance textures
// I_1..I_K and their weights, renormalised per channel so that sum_k w_k = 1 (d'Eon & Luebke 2007,
// 14.4.4: "the weights are normalised so that white light stays white").
#include "common/profile.glsl"
uniform sampler2D uBlur[MAX_GAUSSIANS];  // premultiplied: rgb = I_k x coverage, a = coverage (tsd/blur.frag)

// I_k at uv: bilinear over the premultiplied texels, then normalised by their coverage
vec3 blurred_irradiance(int k, vec2 uv) {
    vec4 t = texture(uBlur[k], uv);
    return t.a > 0.0 ? t.rgb / t.a : vec3(0.0);
}

vec3 diffuse_irradiance(vec2 uv) {
    vec3 E = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        E += uWeights[k] * blurred_irradiance(k, uv);
    }
    return E;
}
