"""Fit the spectral skin presets (profiles/presets.py) to measured skin reflectance.

    PYTHONPATH=src nice -n 10 python benchmarks/fit_skin_presets.py [PRESET ...]   (2-3 minutes a preset, 2 cores)

For each preset, C_m (melanin fraction), beta_m (eumelanin share) and C_h (blood fraction) of
Donner & Jensen 2006 are chosen, with their 0.25 mm epidermis and 75 % oxygenation, so that the
total reflectance R_d(lambda) of the Monte Carlo of its two layers (the reference the presets
render with: monte_carlo_tables.py), in the measurand of its counterpart
(measured_skin.model_measurand), matches the measured spectrum. The Monte Carlo is too slow to
sit inside an optimiser, so the two-layer multipole model stands in for it, times the ratio
MC / multipole of the totals (per wavelength, MC_PHOTONS photons at each of 400-700 nm every
20 nm, interpolated to 10 nm) taken at the current solution: bounded least squares
(scipy.optimize.least_squares) on the log ratios of the three linear-sRGB channels plus, with
weight 0.1, the mean squared log ratio of the 400-700 nm spectrum, first without the ratio, then
with it; then Nelder-Mead on the largest channel |model / measured - 1| (plus the same spectral
term) from there, twice, the ratio renewed at the polished solution in between. The ratio varies
slowly with the parameters (0.8-1.0: the multipole is 2-25 % high, most for dark skin). The
shipped presets except brown were fitted with the largest |log ratio| as the Nelder-Mead
criterion (< 1 % apart); brown's C_m was then set by a scan of the ratio criterion on its
shipped table's MC / multipole (0.0787: red 0.86, blue 1.14 of measured; the fitted point left
blue 15.3 % high). Prints the fitted parameters and the Monte Carlo and pbd colours beside the
measured ones.
"""

import time

import numpy as np
from scipy.optimize import least_squares, minimize

from dermis.profiles.measured_skin import colorchecker_skin, model_measurand, nist_skin
from dermis.profiles.models import layered_diffusion_reflectance, monte_carlo_spectral
from dermis.profiles.monte_carlo_tables import TABLE_WAVELENGTHS_NM
from dermis.profiles.spectral import DEFAULT_WAVELENGTHS_NM, SkinParameters, skin_layers, spectral_to_linear_srgb

# preset: (measured counterpart, fixed beta_m or None). fair and intermediate are the same skins as
# very-light and asian (presets.py), so they are not fitted apart.
TARGETS = {
    "very-light": (lambda: nist_skin("very_light"), None),
    "light": (lambda: nist_skin("light"), None),
    "asian": (lambda: nist_skin("intermediate"), 0.0),  # D&J 2006's Asian skin: pheomelanin only
    "tan": (lambda: nist_skin("tan"), None),
    "brown": (lambda: nist_skin("brown"), None),
    "dark": (lambda: colorchecker_skin("dark skin"), None),
}
MC_PHOTONS = 20_000  # per wavelength: R_d's standard error ~0.7 % (light) to ~2 % (dark, blue)


def monte_carlo_totals(parameters):
    """R_d(lambda) of the Monte Carlo at TABLE_WAVELENGTHS_NM, interpolated to DEFAULT_WAVELENGTHS_NM."""
    totals = monte_carlo_spectral(skin_layers(parameters, TABLE_WAVELENGTHS_NM), MC_PHOTONS, seed=97)[2]
    return np.interp(DEFAULT_WAVELENGTHS_NM, TABLE_WAVELENGTHS_NM, totals)


def measurand(parameters, measured, model):
    totals = layered_diffusion_reflectance(skin_layers(parameters), model).total_reflectance
    return model_measurand(totals, parameters.refractive_index, measured.specular_included)


def fit(measured, fixed_blend):
    target = measured.at(DEFAULT_WAVELENGTHS_NM)
    target_rgb = spectral_to_linear_srgb(target)
    spectral_weight = np.sqrt(0.1 / target.size)

    def unpack(x):
        blend = fixed_blend if fixed_blend is not None else x[1]
        return SkinParameters(x[0], blend, x[2])

    correction = np.ones(target.size)

    def residuals(x):
        spectrum = correction * measurand(unpack(x), measured, "multipole")
        rgb = spectral_to_linear_srgb(spectrum)
        return np.concatenate([np.log(rgb / target_rgb),
                               spectral_weight * np.log(np.maximum(spectrum, 1e-6) / target)])

    def least_squares_fit(starts):
        best = None
        for start in starts:
            result = least_squares(residuals, start, bounds=([0.0, 0.0, 0.0], [0.5, 1.0, 0.2]), diff_step=1e-3,
                                   x_scale=[0.01, 0.3, 0.01], max_nfev=60)
            best = result if best is None or result.cost < best.cost else best
        return best

    best = least_squares_fit(([0.01, 0.3, 0.005], [0.1, 0.7, 0.02]))
    # the multipole totals times MC / multipole at that solution, then again from there
    parameters = unpack(best.x)
    mc = model_measurand(monte_carlo_totals(parameters), parameters.refractive_index, measured.specular_included)
    correction[:] = mc / measurand(parameters, measured, "multipole")
    best = least_squares_fit((best.x,))

    # then minimax from there: the acceptance test is per channel (Nelder-Mead, box by clipping)

    def worst(x):
        x = np.clip(x, [0.0, 0.0, 0.0], [0.5, 1.0, 0.2])
        # the largest |model / measured - 1| of the three channels, as tests/test_profiles_measured.py
        # checks it (brown sits at the model's limit there: 13.8 %; the other presets were fitted with
        # the largest |log ratio| instead, which differs from this by < 1 %)
        return float(np.max(np.abs(np.expm1(residuals(x)[:3]))) + np.sum(residuals(x)[3:] ** 2))

    x = best.x
    for _ in range(2):  # polish, then renew the ratio MC / multipole at the polished solution and polish again
        polished = minimize(worst, x, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-5, "maxfev": 120})
        x = np.clip(polished.x, [0.0, 0.0, 0.0], [0.5, 1.0, 0.2])
        parameters = unpack(x)
        mc = model_measurand(monte_carlo_totals(parameters), parameters.refractive_index, measured.specular_included)
        correction[:] = mc / measurand(parameters, measured, "multipole")
    return unpack(x), polished.fun


def main(names):
    for name, (make, fixed) in TARGETS.items():
        if names and name not in names:
            continue
        start = time.time()
        measured = make()
        parameters, residual = fit(measured, fixed)
        rgb_meas = measured.linear_srgb()
        rgb_pbd = spectral_to_linear_srgb(measurand(parameters, measured, "pbd"))
        mc = model_measurand(monte_carlo_totals(parameters), parameters.refractive_index, measured.specular_included)
        rgb_mc = spectral_to_linear_srgb(mc)
        print(f"{name:13s} C_m={parameters.melanin_fraction:.4f} beta_m={parameters.melanin_blend:.3f} "
              f"C_h={parameters.hemoglobin_fraction:.4f}  cost {residual:.4f}  {measured.name}: "
              f"measured {np.round(rgb_meas, 4)}  MC {np.round(rgb_mc, 4)} ratio {np.round(rgb_mc / rgb_meas, 3)}"
              f"  pbd {np.round(rgb_pbd, 4)} ratio {np.round(rgb_pbd / rgb_meas, 3)}"
              f"  ({time.time() - start:.0f} s)", flush=True)


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
