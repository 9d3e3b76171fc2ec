"""``dermis profile``: compute a skin diffusion profile, fit Gaussians, plot it, write it as JSON.

    dermis profile --preset fair --fit 6 --plot p.png --json p.json    (the preset's shipped Monte Carlo table)
    dermis profile --model multipole --melanin 0.1 --melanin-blend 0.5 --hemoglobin 0.02 --fit 4
    dermis profile --model mc --preset dark --photons 200000 --json dark-mc.json
    dermis profile --model deon --fit 4
    dermis profile --medium layers.toml --model mc --photons 20000    (coefficients per layer: medium_file.py)

A preset's default model is its Monte Carlo table, shipped with dermis (monte_carlo_tables.py: no
run); with other skin parameters the default is pbd, and --model mc runs the Monte Carlo (about
1 s per 10,000 photons and wavelength on 2 cores). The plot shows r R(r) (the energy per unit
radius, 1/mm) per linear-sRGB channel against log radius, with the fitted Gaussians dashed on
top. The JSON (profile_json.py) holds the radii, the RGB profile, the fitted variances and
weights, the fit error and the total reflectance; a scene's [skin] section can load it
(profile = "file.json").
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from dermis.errors import DermisError

MODEL_HELP = ("dipole | multipole | pbd (photon beam diffusion) | burley (Christensen-Burley) | "
              "mc (Monte Carlo; a shipped preset's table, else a run: slow) | deon (d'Eon 2007's six Gaussians). "
              "Default: mc for a preset's parameters (its shipped table), pbd otherwise")


def _parameters(preset, overrides: dict):
    from dermis.profiles.presets import skin_preset
    from dermis.profiles.spectral import SkinParameters

    if preset is None:
        missing = [flag for flag, key in (("--melanin", "melanin_fraction"), ("--hemoglobin", "hemoglobin_fraction"))
                   if key not in overrides]
        if missing:
            raise click.UsageError(f"give --preset NAME or skin parameters ({' and '.join(missing)} missing)")
        base = SkinParameters(0.0, 0.7, 0.0)
    else:
        base = skin_preset(preset)
    return replace(base, **overrides)


def _plot(path, profile, fit, title: str, measured=(), refractive_index: float = 1.4) -> None:
    """r R(r) per channel on a log radius axis, the fit dashed; for a spectral profile a second
    panel with its reflectance spectrum beside measured skin (``measured``: MeasuredSkin, each in
    its own measurand, measured_skin.py). Written atomically as PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from dermis.profiles.profile_json import write_atomic

    r_low = max(1e-3, float(profile.radius_mm[0]))
    r_high = float(min(profile.radius_mm[-1], 60.0))
    radius = np.geomspace(r_low, r_high, 400)
    values = radius[:, None] * profile.evaluate(radius)
    spectral = "wavelength_nm" in profile.spectral
    figure = Figure(figsize=(7.5, 8.0 if spectral else 4.5), dpi=120)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot(2 if spectral else 1, 1, 1)
    colours = ("#d62728", "#2ca02c", "#1f77b4")
    for c, (label, colour) in enumerate(zip("RGB", colours)):
        axes.plot(radius, values[:, c], color=colour, lw=1.8, label=f"{label} profile")
        if fit is not None:
            fitted = radius * fit.profile.evaluate(radius)[:, c]
            axes.plot(radius, fitted, color=colour, lw=1.2, ls="--",
                      label=f"{label} fit, K={fit.profile.k}, error {100 * fit.relative_error_rgb[c]:.2f} %")
    axes.set_xscale("log")
    axes.set_xlabel("radius r (mm)")
    axes.set_ylabel("r R(r)  (1/mm)")
    axes.set_title(title, fontsize=10)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=7, ncol=2 if fit is not None else 1)
    if spectral:
        from dermis.profiles.measured_skin import model_measurand

        wavelength = profile.spectral["wavelength_nm"]
        totals = profile.spectral["total_reflectance"]
        lower = figure.add_subplot(2, 1, 2)
        rgb = model_measurand(profile.total_reflectance_rgb, refractive_index, False)  # linear: per channel too
        lower.plot(wavelength, model_measurand(totals, refractive_index, False), color="k", lw=2.0,
                   label="model, body reflectance (1 - F0) R_d, RGB " + " ".join(f"{v:.3f}" for v in rgb))
        lower.plot(wavelength, model_measurand(totals, refractive_index, True), color="k", lw=1.0, ls="--",
                   label="model + surface reflection F0 (as NIST measures)")
        palette = ("#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#9467bd", "#ff7f0e")
        for i, sample in enumerate(measured):
            keep = (sample.wavelength_nm >= 400) & (sample.wavelength_nm <= 700)
            colour = palette[i % len(palette)]
            lower.plot(sample.wavelength_nm[keep], sample.reflectance[keep], color=colour, lw=1.3,
                       ls="--" if sample.specular_included else "-",
                       label=f"measured: {sample.name}, RGB " + " ".join(f"{v:.3f}" for v in sample.linear_srgb()))
            if sample.spread is not None:
                lower.fill_between(sample.wavelength_nm[keep], (sample.reflectance - sample.spread)[keep],
                                   (sample.reflectance + sample.spread)[keep], color=colour, alpha=0.12, lw=0)
        lower.set_xlabel("wavelength (nm)")
        lower.set_ylabel("reflectance")
        lower.set_xlim(400, 700)
        lower.set_ylim(bottom=0)
        lower.grid(True, alpha=0.3)
        lower.legend(fontsize=6)
        lower.set_title("total reflectance beside measured skin (dashed: specular included)", fontsize=9)
    figure.tight_layout()
    write_atomic(path, lambda stream: figure.savefig(stream, format="png"))


def _rgb(text: str, option: str) -> list[float]:
    """'0.8,0.6,0.5' (or one number for all three) -> three floats."""
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise click.UsageError(f"{option} {text}: expected R,G,B numbers") from None
    if len(values) == 1:
        values *= 3
    if len(values) != 3:
        raise click.UsageError(f"{option} {text}: expected three numbers R,G,B")
    return values


def _check_output(path, suffix: str, option: str):
    if path is None:
        return None
    target = Path(path)
    if target.suffix.lower() != suffix:
        raise click.UsageError(f"{option} {path}: the file name must end in {suffix}")
    if not (target.parent if str(target.parent) else Path(".")).is_dir():
        raise click.UsageError(f"{option} {path}: folder '{target.parent}' does not exist")
    return target


@click.command("profile")
@click.option("--model", type=click.Choice(["dipole", "multipole", "pbd", "burley", "mc", "deon"]), default=None,
              help=MODEL_HELP)
@click.option("--preset", default=None,
              help="fair | asian | dark | very-light | light | intermediate | tan | brown (fitted to measured skin) "
                   "| deon")
@click.option("--melanin", type=float, default=None, help="melanin volume fraction C_m, 0..1")
@click.option("--melanin-blend", type=float, default=None, help="eumelanin share of the melanin beta_m, 0..1 [0.7]")
@click.option("--hemoglobin", type=float, default=None, help="blood volume fraction C_h, 0..1")
@click.option("--oxygenation", type=float, default=None, help="oxygenated share of haemoglobin, 0..1 [0.75]")
@click.option("--epidermis-mm", type=float, default=None, help="epidermis thickness in mm [0.25]; 0: dermis only")
@click.option("--medium", "medium_path", default=None,
              help="a .toml/.json file of optical coefficients per layer (sigma_a, sigma_s' or sigma_s and g, eta, "
                   "thickness_mm; or mfp_mm and albedo) instead of skin parameters")
@click.option("--fit", "fit_k", type=int, default=None, help="fit K Gaussians with shared variances")
@click.option("--plot", "plot_path", default=None, help="write a PNG of r R(r) with the fit")
@click.option("--json", "json_path", default=None, help="write the profile (and fit) as JSON")
@click.option("--photons", type=int, default=None,
              help="Monte Carlo photons per wavelength [100000]; with --photons or --seed a preset is run, "
                   "not read from its shipped table")
@click.option("--seed", type=int, default=None, help="Monte Carlo seed [0]")
@click.option("--illuminant", default="D65", show_default=True, help="CIE illuminant for the RGB integration")
@click.option("--wavelength-step", type=int, default=10, show_default=True,
              help="nm between the wavelengths sampled in 400-700 nm")
@click.option("--albedo", default=None, help="burley, artist-facing: surface albedo R,G,B (linear, 0..1)")
@click.option("--mfp-mm", default=None, help="burley, artist-facing: mean free path R,G,B in mm")
def profile_cmd(model, preset, melanin, melanin_blend, hemoglobin, oxygenation, epidermis_mm, medium_path, fit_k,
                plot_path, json_path, photons, seed, illuminant, wavelength_step, albedo, mfp_mm):
    """Compute a skin diffusion profile from physics, fit Gaussians to it, plot it, save it."""
    from dermis.profiles.fit import fit_sum_of_gaussians
    from dermis.profiles.presets import PRESETS
    from dermis.profiles.profile_json import profile_document, write_profile_json
    from dermis.profiles.models import deon_profile, skin_profile

    plot_target = _check_output(plot_path, ".png", "--plot")
    json_target = _check_output(json_path, ".json", "--json")
    if fit_k is not None and not 1 <= fit_k <= 16:
        raise click.UsageError(f"--fit {fit_k}: the number of Gaussians must lie in 1..16")
    run_options = {"photons": 100_000 if photons is None else photons, "seed": 0 if seed is None else seed}
    if run_options["photons"] < 100:
        raise click.UsageError(f"--photons {photons}: use at least 100")
    if not 1 <= wavelength_step <= 100:
        raise click.UsageError(f"--wavelength-step {wavelength_step}: use 1..100 nm")
    wavelength = np.arange(400.0, 700.0 + 0.5, wavelength_step)
    if preset is not None:
        preset = preset.strip().lower()
        if preset not in PRESETS:
            raise click.UsageError(f"--preset {preset}: unknown (known: {', '.join(PRESETS)})")
    overrides = {key: value for key, value in (
        ("melanin_fraction", melanin), ("melanin_blend", melanin_blend), ("hemoglobin_fraction", hemoglobin),
        ("oxygenation", oxygenation), ("epidermis_thickness_mm", epidermis_mm)) if value is not None}

    if preset == "deon" and model not in (None, "deon"):
        raise click.UsageError(f"--preset deon is d'Eon's Gaussian table; it cannot be computed with --model {model}")
    parameters = None
    if (albedo is None) != (mfp_mm is None):
        raise click.UsageError("--albedo and --mfp-mm go together (the artist-facing Burley profile)")
    if albedo is not None and (model not in (None, "burley") or preset is not None or overrides):
        raise click.UsageError("--albedo/--mfp-mm define a Burley profile: no --preset, skin parameters or other --model")
    if medium_path is not None and (preset is not None or overrides or albedo is not None or model == "deon"):
        raise click.UsageError("--medium gives the optical coefficients: no --preset, skin parameters, --albedo "
                               "or --model deon with it")
    medium = None
    table_note = ""
    try:
        if medium_path is not None:
            from dermis.profiles.medium_file import read_medium_file
            from dermis.profiles.models import medium_profile

            try:
                layers, medium_wavelength = read_medium_file(medium_path)
            except DermisError as exc:
                raise click.UsageError(f"--medium {exc}") from None
            model = model or "pbd"
            medium = (layers, medium_wavelength)
            profile = medium_profile(layers, model, wavelength_nm=medium_wavelength, illuminant=illuminant,
                                     progress=model == "mc", name=Path(medium_path).stem, **run_options)
        elif albedo is not None:
            from dermis.profiles.models import burley_artist_profile

            model, profile = "burley", burley_artist_profile(_rgb(albedo, "--albedo"), _rgb(mfp_mm, "--mfp-mm"))
        elif model == "deon" or preset == "deon":
            if overrides or (preset not in (None, "deon")):
                raise click.UsageError("--model deon is a fixed table: it takes no preset or skin parameters")
            model, profile = "deon", deon_profile()
        else:
            from dermis.profiles.monte_carlo_tables import shipped_table

            parameters = _parameters(preset, overrides)
            table = shipped_table(parameters) if model in (None, "mc") and photons is None and seed is None else None
            if table is not None:
                model, wavelength = "mc", table.wavelength_nm
                profile = table.profile(illuminant, name=preset or "physical")
                table_note = (f"  Monte Carlo table shipped with dermis: {table.photons} photons per wavelength, "
                              f"seed {table.seed}, {wavelength.size} wavelengths {wavelength[0]:g}-{wavelength[-1]:g} nm")
            else:
                model = model or "pbd"
                profile = skin_profile(parameters, model, wavelength_nm=wavelength, illuminant=illuminant,
                                       progress=model == "mc", name=preset or "physical", **run_options)
        # a Monte Carlo profile is fitted from MC_FIT_MIN_RADIUS_MM out, as a scene fits it (scene_skin.py)
        from dermis.profiles.scene_skin import MC_FIT_MIN_RADIUS_MM

        r_min = MC_FIT_MIN_RADIUS_MM if model == "mc" else 0.0
        fit = fit_sum_of_gaussians(profile, fit_k, r_min_mm=r_min) if fit_k is not None else None
    except DermisError as exc:
        raise click.ClickException(str(exc)) from None

    label = profile.name if model != "deon" else "deon"
    click.echo(f"profile: {label}, model {model}")
    if table_note:
        click.echo(table_note)
    if medium is not None:
        for i, layer in enumerate(medium[0]):
            thickness = "semi-infinite" if layer.semi_infinite else f"{layer.thickness_mm:g} mm"
            click.echo(f"  layer {i + 1}: {thickness}, g {layer.medium.g:g}, eta {layer.medium.n:g}")
    if parameters is not None:
        click.echo("  melanin %.4g, blend %.3g, hemoglobin %.4g, oxygenation %.3g, epidermis %.3g mm"
                   % (parameters.melanin_fraction, parameters.melanin_blend, parameters.hemoglobin_fraction,
                      parameters.oxygenation, parameters.epidermis_thickness_mm))
    click.echo("  total diffuse reflectance (linear sRGB): " + " ".join(f"{v:.4f}" for v in profile.total_reflectance_rgb))
    click.echo("  mean radius (mm): " + " ".join(f"{v:.3f}" for v in profile.mean_radius_mm()))
    if fit is not None:
        click.echo(f"  fit: {fit.profile.k} Gaussians, r-weighted relative L2 error "
                   + " ".join(f"{100 * v:.2f}%" for v in fit.relative_error_rgb)
                   + (f" (shape from {r_min:g} mm out)" if r_min > 0 else ""))
        for v, w in zip(fit.profile.variances_mm2, fit.profile.weights):
            click.echo(f"    variance {v:9.5f} mm^2   weights {w[0]:.4f} {w[1]:.4f} {w[2]:.4f}")

    document = profile_document(profile, fit, parameters.to_dict() if parameters is not None else None,
                                illuminant if model != "deon" else None)
    # The optical coefficients behind the profile (1/mm, mm), for skin parameters and --medium alike
    if medium is not None or parameters is not None:
        from dermis.profiles.medium_file import medium_document
        from dermis.profiles.spectral import skin_layers

        layers, medium_wavelength = medium if medium is not None else (skin_layers(parameters, wavelength), wavelength)
        document["medium"] = medium_document(layers, medium_wavelength)
    try:
        if json_target is not None:
            write_profile_json(json_target, document)
            click.echo(f"wrote {json_target}")
        if plot_target is not None:
            title = f"{label} skin, {model} model" + (f", {fit.profile.k}-Gaussian fit" if fit is not None else "")
            from dermis.profiles.measured_skin import measured_for_plot

            index = medium[0][0].medium.n if medium is not None else (
                parameters.refractive_index if parameters is not None else 1.4)
            _plot(plot_target, profile, fit, title, measured_for_plot(preset), index)
            click.echo(f"wrote {plot_target}")
    except (OSError, DermisError) as exc:
        raise click.ClickException(f"cannot write output: {exc}") from None
