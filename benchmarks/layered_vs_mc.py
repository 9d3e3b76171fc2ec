"""Layered skin: each diffusion model's R(r) against the Monte Carlo of the same layers.

    PYTHONPATH=src python benchmarks/layered_vs_mc.py [photons per wavelength, default 20000]

Per preset (and issue 13's two-layer case: melanin 0, haemoglobin 0.005, epidermis 0.25 mm), at
450, 550 and 650 nm: the MCML Monte Carlo (monte_carlo.py) binned radially, and the pbd,
multipole and dipole layered models (layers.py) averaged over the same bins; the r-weighted L2
difference sqrt(sum r dr (model - MC)^2 / sum r dr MC^2) over 0.1-10 mm, the MC's own relative
standard error of that norm, the totals, and the ratio model/MC at 2 mm. Prints a markdown table.
"""

import sys
import time

import numpy as np
from scipy.integrate import trapezoid

from dermis.profiles.models import MONTE_CARLO_BIN_EDGES_MM, layered_diffusion_reflectance
from dermis.profiles.monte_carlo import monte_carlo_reflectance
from dermis.profiles.medium import Layer
from dermis.profiles.presets import SKIN_PRESETS
from dermis.profiles.spectral import SkinParameters, skin_layers

WAVELENGTHS_NM = np.array([450.0, 550.0, 650.0])
CASES = {"issue 13 two-layer": SkinParameters(0.0, 0.7, 0.005), "fair": SKIN_PRESETS["fair"],
         "asian": SKIN_PRESETS["asian"], "dark": SKIN_PRESETS["dark"]}


def bin_average(radius, values, edges):
    """Mean of a profile (1/mm^2) over each annulus [e_i, e_i+1): integral 2 pi r R dr / area."""
    out = np.zeros((edges.size - 1,) + values.shape[1:])
    for i in range(edges.size - 1):
        r = np.geomspace(max(edges[i], 1e-5), edges[i + 1], 64)
        v = np.stack([np.interp(np.log(r), np.log(radius), values[:, j]) for j in range(values.shape[1])], -1)
        out[i] = trapezoid(2 * np.pi * r[:, None] * v, r, axis=0) / (np.pi * (edges[i + 1] ** 2 - edges[i] ** 2))
    return out


def main(photons: int):
    edges = MONTE_CARLO_BIN_EDGES_MM
    centres = np.sqrt(edges[1:] * np.maximum(edges[:-1], 1e-3))
    width = np.diff(edges)
    keep = (centres >= 0.1) & (centres <= 10.0)
    print("| case | nm | MC R_d | pbd | multipole | dipole | MC s.e. of the norm | pbd/MC at 2 mm |")
    print("|---|---|---|---|---|---|---|---|")
    for name, parameters in CASES.items():
        layers = skin_layers(parameters, WAVELENGTHS_NM)
        models = {m: layered_diffusion_reflectance(layers, m) for m in ("pbd", "multipole", "dipole")}
        for i, wavelength in enumerate(WAVELENGTHS_NM):
            start = time.time()
            stack = [Layer(layer.medium.select([i]), layer.thickness_mm) for layer in layers]
            mc = monte_carlo_reflectance(stack, photons, edges, seed=11 + i)
            seconds = time.time() - start
            reference = mc.reflectance_per_mm2
            weight = centres * width
            norm = np.sqrt(np.sum(weight[keep] * reference[keep] ** 2))
            noise = np.sqrt(np.sum(weight[keep] * mc.standard_error_per_mm2[keep] ** 2)) / norm
            cells = [f"{float(mc.total_reflectance):.3f}"]
            at2 = ""
            for m, result in models.items():
                averaged = bin_average(result.grid.radius_mm, result.reflectance[:, i:i + 1], edges)[:, 0]
                error = np.sqrt(np.sum(weight[keep] * (averaged[keep] - reference[keep]) ** 2)) / norm
                cells.append(f"{100 * error:.1f} % (R_d {result.total_reflectance[i]:.3f})")
                if m == "pbd":
                    j = np.argmin(np.abs(centres - 2.0))
                    at2 = f"{averaged[j] / reference[j]:.2f}"
            print(f"| {name} | {wavelength:.0f} | " + " | ".join(cells) + f" | {100 * noise:.1f} % | {at2} |"
                  f"  <!-- MC {photons} photons {seconds:.0f} s -->", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20000)
