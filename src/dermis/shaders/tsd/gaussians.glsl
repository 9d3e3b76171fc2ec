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

// sum_k w_k I_k with the detail that I_1's texels cannot hold (tsd/final.frag with PIXEL_DETAIL):
// where a texel is wider than the narrow Gaussians (the head's ear at the adaptive size: texels of
// ~1.3 mm against sigma 0.08-0.43 mm), the texture point-samples at its texel centres an irradiance
// that turns faster than the texels across a fold, and the narrow terms show that sampling as a
// comb of stripes. The residual R = I_0(pixel) - I_1(uv) is that part: the light the texture's
// reconstruction leaves out, at frequencies at or above the texture's Nyquist frequency 1 / (2 t)
// (t = 1 / texels_per_mm, mm). G(v_k) passes a frequency f by exp(-2 pi^2 v_k f^2), so at that
// frequency each term keeps a_k = exp(-pi^2 v_k / (2 t^2)) of R: ~1 for the Gaussians far narrower
// than a texel (the per-pixel irradiance IS their blur there), ~0 for the wide ones, which the
// texture holds. Where the texture resolves the irradiance, R ~ 0 and this is diffuse_irradiance.
// weight in [0, 1] scales R (0: diffuse_irradiance).
vec3 diffuse_irradiance_detail(vec2 uv, vec3 I0_pixel, float texels_per_mm, float weight) {
    vec3 I1 = blurred_irradiance(0, uv);
    vec3 R = weight * (I0_pixel - I1);
    float q = 0.5 / (INV_PI * INV_PI) * texels_per_mm * texels_per_mm;  // pi^2 / (2 t^2), per mm^2
    vec3 E = uWeights[0] * (I1 + exp(-q * uVariances[0]) * R);
    for (int k = 1; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        E += uWeights[k] * (blurred_irradiance(k, uv) + exp(-q * uVariances[k]) * R);
    }
    return E;
}
