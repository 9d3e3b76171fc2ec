// The active diffusion profile as uniforms: a sum of K <= MAX_GAUSSIANS Gaussians
// sum_k w_k G(v_k, r) with variances in mm^2 shared by R, G and B and per-channel weights
// renormalised so that sum_k w_k = 1 per channel (d'Eon & Luebke 2007, 14.4.4: "white light stays
// white"; the colour comes from the albedo). Set by dermis.techniques.shared.set_profile_uniforms;
// MAX_GAUSSIANS comes from there too (or a program's own #define: ssss compiles for exactly K).
#include "common/constants.glsl"
uniform int uGaussianCount;
uniform vec3 uWeights[MAX_GAUSSIANS];
uniform float uVariances[MAX_GAUSSIANS];  // mm^2
