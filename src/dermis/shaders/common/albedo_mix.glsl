// Pre- and post-scatter albedo (d'Eon & Luebke 2007, 14.5.2): albedo^mix multiplies the irradiance
// before scattering and albedo^(1 - mix) the scattered light after. x^0 = 1 for every x, as the
// limit mix -> 1 of the model requires (the colour all taken before scattering); GLSL leaves
// pow(0, 0) undefined and llvmpipe returns 0 or NaN, so a black albedo texel came out black
// with mix = 1 although scattered light arrives there.
vec3 albedo_power(vec3 albedo, float exponent) {
    return exponent > 0.0 ? pow(max(albedo, vec3(0.0)), vec3(exponent)) : vec3(1.0);
}
