// The thin-slab transmittance of the medium the profile describes (dermis/profiles/thin_slab.py:
// diffusion theory in one dimension, a source at z_0 = 1/sigma_t', fluence zero z_b = 2 A D outside
// both faces):  T(d) = alpha' sinh(kappa (z_0 + z_b)) / sinh(kappa (d + 2 z_b)), per channel, over
// the skin albedo A_c it was solved for (the shading multiplies by the albedo itself). Units: mm.
uniform vec3 uSlabReducedAlbedo;  // alpha'
uniform vec3 uSlabKappa;          // sigma_tr, 1/mm
uniform vec3 uSlabSourceDepth;    // z_0, mm
uniform vec3 uSlabExtrapolation;  // z_b, mm
uniform vec3 uSlabAlbedo;         // A_c

vec3 slab_transmittance(float d_mm) {
    vec3 z0 = min(uSlabSourceDepth, vec3(d_mm));
    vec3 a = uSlabKappa * (z0 + uSlabExtrapolation);
    vec3 b = uSlabKappa * (d_mm + 2.0 * uSlabExtrapolation);
    // sinh(a) / sinh(b) = e^(a - b) (1 - e^(-2a)) / (1 - e^(-2b)): no overflow for thick tissue
    vec3 ratio = exp(a - b) * (1.0 - exp(-2.0 * a)) / max(1.0 - exp(-2.0 * b), vec3(1e-30));
    return uSlabReducedAlbedo * ratio / max(uSlabAlbedo, vec3(1e-4));
}

// The per-axis variance (mm^2) of where the light leaving the far boundary of a d mm slab left it,
// about the point it entered the other face: the law's transform across the faces (kappa ->
// sqrt(kappa^2 + q^2)) is T(q) = alpha' sinh(k_q a) / sinh(k_q b), a = z_0 + z_b, b = d + 2 z_b, and
// -d^2 ln T / dq^2 at q = 0 is the variance: [b coth(kappa b) - a coth(kappa a)] / kappa
// (SlabLaw.transmitted_variance, tests/test_slab_theory.py). Against the slab's Monte Carlo
// (benchmarks/RESULTS.md, round 7: 2.05 / 3.47 / 6.31 mm^2 at 2 / 3 / 5 mm, red) it is 1.2-1.4x
// wider from 2 mm on, 2.8x at 0.5 mm. Per channel.
vec3 slab_transmitted_variance(float d_mm) {
    vec3 a = min(uSlabSourceDepth, vec3(d_mm)) + uSlabExtrapolation;
    vec3 b = d_mm + 2.0 * uSlabExtrapolation;
    vec3 k = max(uSlabKappa, vec3(1e-3));
    // tanh clamped where it is 1 in float32 (tanh(x) = (e^2x - 1) / (e^2x + 1) overflows past x ~ 44)
    return (b / tanh(min(k * b, vec3(20.0))) - a / tanh(min(k * a, vec3(20.0)))) / k;
}
