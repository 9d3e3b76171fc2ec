"""Each spectral preset's total reflectance beside its measured counterpart (a markdown table).

    PYTHONPATH=src python benchmarks/preset_reflectance.py     (a few seconds; no Monte Carlo run)

Per preset: its parameters, its counterpart (presets.MEASURED_COUNTERPARTS) in linear sRGB under
D65, the rendered total reflectance (the shipped Monte Carlo table's R_d, monte_carlo_tables.py)
and the pbd model's, each in the counterpart's measurand (measured_skin.model_measurand), all
integrated over the table's wavelengths (400-700 nm every 20 nm), and the ratios model / measured.
Then the ColorChecker "light skin" patch (no preset's counterpart, see presets.py) beside the
presets nearest it, with every patch's and category's ITA.
"""

import numpy as np

from dermis.profiles.measured_skin import colorchecker_skin, measured_counterpart, model_measurand
from dermis.profiles.models import layered_diffusion_reflectance
from dermis.profiles.monte_carlo_tables import shipped_tables
from dermis.profiles.presets import SKIN_PRESETS
from dermis.profiles.spectral import skin_layers, spectral_to_linear_srgb


def colours(name, measured):
    table = shipped_tables()[name]
    parameters, wavelength = SKIN_PRESETS[name], table.wavelength_nm
    n, specular = parameters.refractive_index, measured.specular_included
    mc = spectral_to_linear_srgb(model_measurand(table.total_reflectance, n, specular), wavelength)
    pbd_totals = layered_diffusion_reflectance(skin_layers(parameters, wavelength), "pbd").total_reflectance
    pbd = spectral_to_linear_srgb(model_measurand(pbd_totals, n, specular), wavelength)
    return measured.linear_srgb(wavelength), mc, pbd


def triple(values, digits=3):
    return " / ".join(f"{v:.{digits}f}" for v in values)


def main():
    print("| preset | C_m, beta_m, C_h | measured counterpart (ITA) | measured R / G / B | rendered (MC) R / G / B "
          "| MC / measured | pbd / measured |")
    print("|---|---|---|---|---|---|---|")
    for name, parameters in SKIN_PRESETS.items():
        measured = measured_counterpart(name)
        target, mc, pbd = colours(name, measured)
        print(f"| {name} | {parameters.melanin_fraction:.4f}, {parameters.melanin_blend:g}, "
              f"{parameters.hemoglobin_fraction:.4f} | {measured.name} ({measured.individual_typology_angle():.1f} deg) "
              f"| {triple(target)} | {triple(mc)} | {triple(mc / target, 2)} | {triple(pbd / target, 2)} |")
    patch = colorchecker_skin("light skin")
    print(f"\n{patch.name} (ITA {patch.individual_typology_angle():.1f} deg), body reflectance "
          f"{triple(patch.linear_srgb(shipped_tables()['fair'].wavelength_nm))}:")
    for name in ("very-light", "light"):
        target, mc, _ = colours(name, patch)
        print(f"  {name}: rendered {triple(mc)}, ratio {triple(mc / target, 2)}")


if __name__ == "__main__":
    main()
