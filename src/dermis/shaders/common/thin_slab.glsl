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
