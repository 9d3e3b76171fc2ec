"""Each layered preset: every profile model against the shipped Monte Carlo table of the same layers.

    PYTHONPATH=src python benchmarks/presets_vs_mc.py [--plot benchmarks/presets_vs_mc.png]   (about a minute)

Per preset (presets sharing parameters once), in linear sRGB: the Monte Carlo table
(monte_carlo_tables.py, shipped; no run here), the pbd, multipole, dipole and Burley models, and the
6 Gaussians a scene renders the preset with (fitted to the table), each averaged over the table's
annuli; the r-weighted L2 difference over 0.1-10 mm per channel (monte_carlo_tables.shape_difference),
the table's own noise in that norm, and the totals. Prints a markdown table; the plot draws
r R(r) of the table (with +-2 standard errors) and of each model.
"""

import argparse

import numpy as np

from dermis.profiles.fit import fit_sum_of_gaussians
from dermis.profiles.models import skin_profile
from dermis.profiles.monte_carlo_tables import shape_difference, shipped_tables
from dermis.profiles.scene_skin import MC_FIT_MIN_RADIUS_MM

MODELS = ("pbd", "multipole", "dipole", "burley")


def main(plot_path):
    tables, seen = [], set()
    for name, table in shipped_tables().items():
        if table.parameters not in seen:
            seen.add(table.parameters)
            tables.append((name, table))
    print("| preset | MC R_d (R / G / B) | MC noise | 6 Gaussians (rendered) | pbd | multipole | dipole | burley |")
    print("|---|---|---|---|---|---|---|---|")
    curves = {}
    for name, table in tables:
        reference = table.profile()
        profiles = {m: skin_profile(table.parameters, m, wavelength_nm=table.wavelength_nm) for m in MODELS}
        fit = fit_sum_of_gaussians(reference, 6, r_min_mm=MC_FIT_MIN_RADIUS_MM)
        cells = []
        difference, noise = shape_difference(fit.profile.evaluate, table)
        cells.append(" / ".join(f"{100 * v:.1f}" for v in difference) + " %")
        for m in MODELS:
            difference, _ = shape_difference(profiles[m].evaluate, table)
            totals = profiles[m].total_reflectance_rgb
            cells.append(" / ".join(f"{100 * v:.0f}" for v in difference) + " % (R_d "
                         + " / ".join(f"{v:.3f}" for v in totals) + ")")
        print(f"| {name} | " + " / ".join(f"{v:.3f}" for v in reference.total_reflectance_rgb)
              + " | " + " / ".join(f"{100 * v:.1f}" for v in noise) + " % | " + " | ".join(cells) + " |", flush=True)
        curves[name] = (reference, profiles, fit)
    if plot_path:
        plot(plot_path, curves)
        print(f"wrote {plot_path}")


def plot(path, curves):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = len(curves)
    figure = Figure(figsize=(12, 2.6 * rows), dpi=100)
    FigureCanvasAgg(figure)
    radius = np.geomspace(0.05, 20.0, 300)
    styles = {"pbd": "--", "multipole": ":", "dipole": "-.", "burley": (0, (1, 3)), "6 Gaussians": "-"}
    for row, (name, (reference, profiles, fit)) in enumerate(curves.items()):
        mc_r = reference.radius_mm
        keep = (mc_r >= 0.05) & (mc_r <= 20)
        for c, channel in enumerate("RGB"):
            axes = figure.add_subplot(rows, 3, 3 * row + c + 1)
            value = mc_r[keep] * reference.rgb_per_mm2[keep, c]
            error = 2 * mc_r[keep] * reference.standard_error_rgb_per_mm2[keep, c]
            axes.fill_between(mc_r[keep], value - error, value + error, color="k", alpha=0.2, lw=0)
            axes.plot(mc_r[keep], value, "k.", ms=3, label="Monte Carlo (table, +-2 s.e.)")
            for m, profile in profiles.items():
                axes.plot(radius, radius * profile.evaluate(radius)[:, c], ls=styles[m], lw=1.1, label=m)
            axes.plot(radius, radius * fit.profile.evaluate(radius)[:, c], color="tab:red", lw=0.9,
                      label="6 Gaussians (rendered)")
            axes.set_xscale("log")
            axes.set_title(f"{name}, {channel}", fontsize=9)
            axes.grid(True, which="both", alpha=0.3)
            if row == rows - 1:
                axes.set_xlabel("radius (mm)")
            if c == 0:
                axes.set_ylabel("r R(r) (1/mm)")
            if row == 0 and c == 0:
                axes.legend(fontsize=6)
    figure.tight_layout()
    figure.savefig(path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--plot", default=None)
    main(parser.parse_args().plot)
