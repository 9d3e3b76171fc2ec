"""A scene's [skin] section -> the SumOfGaussians every technique blurs with.

    [skin]
    profile = "deon"            # default: d'Eon et al. 2007's six Gaussians
    profile = "fair"            # a preset (presets.py): fair, asian, dark, very-light, light,
                                #   intermediate, tan, brown
    profile = "physical"        # skin parameters:
    melanin = 0.05              #   C_m, melanin volume fraction      (required)
    hemoglobin = 0.01           #   C_h, blood volume fraction        (required)
    melanin_blend = 0.7         #   beta_m, eumelanin share           (default 0.7)
    oxygenation = 0.75          #   gamma, oxy-haemoglobin share      (default 0.75)
    epidermis_mm = 0.25         #   epidermis thickness               (default 0.25)
    model = "mc"                #   dipole, multipole, pbd, burley or mc. Default: mc for a shipped
                                #   preset's parameters (its Monte Carlo table, shipped: instant),
                                #   pbd for any other skin; mc for other skin runs the Monte
                                #   Carlo, ~1-2 min once (2 cores), then cached on disk
    gaussians = 6               #   K, the number of Gaussians        (default 6)
    profile = "skin.json"       # a file written by `dermis profile --json` (relative to the scene)
    profile = "medium"          # optical coefficients per layer (profiles/medium_file.py), top first:
    [[skin.layer]]              #   sigma_a, sigma_s_reduced (or sigma_s and g), eta, thickness_mm,
    sigma_a = [0.3, 0.6, 1.2]   #   or mfp_mm and albedo; 1 value or R,G,B (or one per
    sigma_s_reduced = 2.5       #   [skin] wavelength_nm = [...]); model and gaussians apply
    thickness_mm = 0.1
    [[skin.layer]]
    mfp_mm = [1.2, 0.6, 0.3]
    albedo = [0.995, 0.98, 0.95]

A preset accepts the physical keys too, as overrides of its values (then it is other skin: its
default model is pbd, whose shape is 7-28 % off the Monte Carlo, benchmarks/RESULTS.md). The weights of the result
carry colour: per channel they split the total diffuse reflectance among the Gaussians (the
renderer may normalise them). Results are cached in memory and on disk (under
$DERMIS_CACHE_DIR, else $XDG_CACHE_HOME/dermis, else ~/.cache/dermis; DERMIS_CACHE_DIR=off
disables the disk cache); a physical profile and its fit take about 1 s when not cached.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.profiles.gaussians import SumOfGaussians, deon_skin

PHYSICAL_KEYS = {"melanin": "melanin_fraction", "melanin_blend": "melanin_blend",
                 "hemoglobin": "hemoglobin_fraction", "oxygenation": "oxygenation",
                 "epidermis_mm": "epidermis_thickness_mm"}
MEDIUM_KEYS = ("layer", "wavelength_nm")
SKIN_KEYS = ("profile", *PHYSICAL_KEYS, "model", "gaussians", *MEDIUM_KEYS)
SCENE_MODELS = ("dipole", "multipole", "pbd", "burley", "mc")
#: model = "mc": the Monte Carlo's R(r) as the shape the Gaussians are fitted to (the layered
#: diffusion models lose lateral transport across a thin epidermis: pbd's red tail is 15-40 % low
#: at 2 mm, benchmarks/RESULTS.md). The shipped presets' tables ship (monte_carlo_tables.py);
#: for other skin: photons per wavelength and the wavelengths it samples, about 1 s per 10,000
#: photons and wavelength on 2 cores, so about 1-2 minutes once, then read from the disk cache.
MC_SCENE_PHOTONS = 50_000
#: Gaussians fitted to a Monte Carlo profile match its shape from this radius out (mm); the
#: energy within it still counts through the weights' sum. Within ~0.05 mm the isotropic
#: single-scattering peak (~1/r) dominates, far below a texel of any irradiance texture or screen
#: pixel; fitted from r = 0 the narrow peak takes the widest Gaussians' weights from the tail (dark
#: skin's blue: 13 % r-weighted error over 0.1-10 mm, 2.4 % from 0.05 mm, tests/test_profiles_mc_tables.py).
MC_FIT_MIN_RADIUS_MM = 0.05
MC_SCENE_WAVELENGTHS_NM = np.arange(400.0, 701.0, 20.0)
CACHE_VERSION = 3  # bump when a model's numbers change (2: multipole thin-slab pole depth; 3: MC tables)


def _cache_folder() -> Path | None:
    setting = os.environ.get("DERMIS_CACHE_DIR")
    if setting is not None:
        return None if setting.strip().lower() in ("", "0", "off", "none") else Path(setting)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "dermis"


def _disk_cache_path(key: str) -> Path | None:
    folder = _cache_folder()
    if folder is None:
        return None
    return folder / "profiles" / (hashlib.sha256(key.encode()).hexdigest()[:32] + ".json")


@lru_cache(maxsize=64)
def _fitted_physical(model: str, parameters: tuple, k: int):
    """(variances, weights, relative error) of a physical profile's K-Gaussian fit, cached."""
    from dermis.profiles import models
    from dermis.profiles.fit import fit_sum_of_gaussians
    from dermis.profiles.spectral import DEFAULT_WAVELENGTHS_NM, SkinParameters

    if model == "mc":
        from dermis.profiles.monte_carlo_tables import shipped_table

        table = shipped_table(SkinParameters(*parameters))
        if table is not None:  # a shipped preset: its tabulated Monte Carlo, no run
            key = json.dumps([CACHE_VERSION, "mc-table", table.name, table.digest(), k, MC_FIT_MIN_RADIUS_MM])
            return _cached_fit(key, lambda: fit_sum_of_gaussians(table.profile(), k, r_min_mm=MC_FIT_MIN_RADIUS_MM))
        wavelength, options = MC_SCENE_WAVELENGTHS_NM, {"photons": MC_SCENE_PHOTONS}
        r_min = MC_FIT_MIN_RADIUS_MM
    else:
        wavelength, options, r_min = DEFAULT_WAVELENGTHS_NM, {}, 0.0
    key = json.dumps([CACHE_VERSION, model, parameters, k, wavelength.tolist(), options, r_min])
    return _cached_fit(key, lambda: fit_sum_of_gaussians(
        models.skin_profile(SkinParameters(*parameters), model, wavelength_nm=wavelength, **options), k,
        r_min_mm=r_min))


def default_model(parameters) -> str:
    """"mc" for the parameters of a shipped preset (its Monte Carlo table ships), else "pbd"."""
    from dermis.profiles.monte_carlo_tables import shipped_table

    return "mc" if shipped_table(parameters) is not None else "pbd"


def physical_gaussians(parameters, model: str | None = None, k: int = 6, name: str = "physical") -> SumOfGaussians:
    """The K-Gaussian fit of the skin profile of ``parameters`` (SkinParameters), cached.
    ``model`` None: default_model(parameters)."""
    from dermis.profiles.fit import _check_k

    model = default_model(parameters) if model is None else model
    if model not in SCENE_MODELS:
        raise DermisError(f"model '{model}' is not available here (use {', '.join(SCENE_MODELS)})")
    k = _check_k(k)
    fields = (parameters.melanin_fraction, parameters.melanin_blend, parameters.hemoglobin_fraction,
              parameters.oxygenation, parameters.epidermis_thickness_mm, parameters.refractive_index,
              parameters.anisotropy)
    variances, weights, _ = _fitted_physical(model, tuple(float(v) for v in fields), k)
    return SumOfGaussians(np.array(variances), np.array(weights), name)


def _cached_fit(key: str, compute):
    """(variances, weights, error) stored on disk under ``key`` or computed by ``compute()``."""
    path = _disk_cache_path(key)
    if path is not None and path.is_file():
        try:
            stored = json.loads(path.read_text())
            if stored.get("key") == key:
                return tuple(stored["variances_mm2"]), tuple(map(tuple, stored["weights_rgb"])), stored["error"]
        except (OSError, ValueError, KeyError, TypeError):
            pass  # a damaged cache entry is recomputed
    fit = compute()
    result = (tuple(fit.profile.variances_mm2.tolist()), tuple(map(tuple, fit.profile.weights.tolist())),
              fit.relative_error)
    if path is not None:
        try:
            from dermis.profiles.profile_json import write_atomic

            path.parent.mkdir(parents=True, exist_ok=True)
            text = json.dumps({"key": key, "variances_mm2": result[0], "weights_rgb": result[1],
                               "error": result[2]}).encode()
            write_atomic(path, lambda stream: stream.write(text))
        except (OSError, DermisError):
            pass  # the cache is an optimisation only
    return result


@lru_cache(maxsize=32)
def _fitted_medium(model: str, description: str, k: int):
    from dermis.profiles.fit import fit_sum_of_gaussians
    from dermis.profiles.medium_file import layers_from_description
    from dermis.profiles.models import medium_profile

    def compute():
        layers, wavelength = layers_from_description(json.loads(description), "[skin]")
        options = {"photons": MC_SCENE_PHOTONS} if model == "mc" else {}
        return fit_sum_of_gaussians(medium_profile(layers, model, wavelength_nm=wavelength, **options), k,
                                    r_min_mm=MC_FIT_MIN_RADIUS_MM if model == "mc" else 0.0)

    return _cached_fit(json.dumps([CACHE_VERSION, "medium", model, description, k, MC_FIT_MIN_RADIUS_MM]), compute)


def medium_gaussians(description: dict, model: str = "pbd", k: int = 6, name: str = "medium") -> SumOfGaussians:
    """The K-Gaussian fit of the profile of a medium description (medium_file.py), cached."""
    from dermis.profiles.fit import _check_k
    from dermis.profiles.medium_file import layers_from_description

    if model not in SCENE_MODELS:
        raise DermisError(f"model '{model}' is not available here (use {', '.join(SCENE_MODELS)})")
    layers_from_description(description, "[skin]")  # validate before the cache sees it
    variances, weights, _ = _fitted_medium(model, json.dumps(description, sort_keys=True), _check_k(k))
    return SumOfGaussians(np.array(variances), np.array(weights), name)


@lru_cache(maxsize=8)
def _refit_deon(k: int):
    from dermis.profiles.fit import fit_sum_of_gaussians
    from dermis.profiles.models import deon_profile

    fit = fit_sum_of_gaussians(deon_profile(), k)
    return fit.profile.variances_mm2.tolist(), fit.profile.weights.tolist()


def _number(section, key, source):
    value = section[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DermisError(f"{source}: [skin] {key} must be a number, got {value!r}")
    return float(value)


def resolve_skin_profile(section: dict, base_dir: Path, source: str) -> SumOfGaussians:
    """The SumOfGaussians of a scene's [skin] table (see the module docstring for the keys)."""
    from dermis.profiles.presets import SKIN_PRESETS, PRESETS
    from dermis.profiles.spectral import SkinParameters

    if not isinstance(section, dict):
        raise DermisError(f"{source}: [skin] must be a table")
    for key in section:
        if key not in SKIN_KEYS:
            raise DermisError(f"{source}: unknown key '{key}' in [skin] (known: {', '.join(SKIN_KEYS)})")
    profile = section.get("profile", "deon")
    if not isinstance(profile, str) or not profile.strip() or any(c < " " for c in profile):  # a NUL names no file
        shown = profile[:200] if isinstance(profile, str) else profile
        raise DermisError(f"{source}: [skin] profile must be a name or a file, got {shown!r}")
    k = section.get("gaussians")
    if k is not None and (isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= 16):
        raise DermisError(f"{source}: [skin] gaussians must be an integer in 1..16, got {k!r}")
    physical = {key: _number(section, key, source) for key in PHYSICAL_KEYS if key in section}
    model = section.get("model")
    name = profile.strip().lower()
    medium_keys = [key for key in MEDIUM_KEYS if key in section]
    if name == "medium":
        if physical:
            raise DermisError(f"{source}: [skin] '{next(iter(physical))}' does not apply to profile = \"medium\"")
        if model is not None and model not in SCENE_MODELS:
            raise DermisError(f"{source}: [skin] model '{model}' is unknown (use {', '.join(SCENE_MODELS)})")
        description = {key: section[key] for key in medium_keys}
        try:
            return medium_gaussians(description, model or "pbd", k or 6, "medium")
        except DermisError as exc:
            raise DermisError(f"{source}: {exc}") from None
    if medium_keys:
        raise DermisError(f"{source}: [skin] '{medium_keys[0]}' needs profile = \"medium\"")

    if name in SKIN_PRESETS or name == "physical":
        if model is not None and model not in SCENE_MODELS:
            raise DermisError(f"{source}: [skin] model '{model}' is unknown (use {', '.join(SCENE_MODELS)})")
        if name == "physical":
            missing = [key for key in ("melanin", "hemoglobin") if key not in physical]
            if missing:
                raise DermisError(f"{source}: [skin] profile = \"physical\" needs '{missing[0]}'")
        try:
            base = SkinParameters(0.0, 0.7, 0.0) if name == "physical" else SKIN_PRESETS[name]
            parameters = replace(base, **{PHYSICAL_KEYS[key]: value for key, value in physical.items()})
        except DermisError as exc:
            raise DermisError(f"{source}: [skin] {exc}") from None
        return physical_gaussians(parameters, model, k or 6, name)

    extras = [key for key in (*PHYSICAL_KEYS, "model") if key in section]
    if name == "deon":
        if extras:
            raise DermisError(f"{source}: [skin] '{extras[0]}' does not apply to profile = \"deon\"")
        if k is None or k == 6:
            return deon_skin()
        variances, weights = _refit_deon(k)
        return SumOfGaussians(np.array(variances), np.array(weights), f"deon-{k}")

    # A profile file written by `dermis profile --json`, relative to the scene's folder
    if not profile.lower().endswith(".json"):
        raise DermisError(f"{source}: [skin] profile '{profile}' is unknown "
                          f"(use {', '.join(PRESETS)}, physical, medium, or a profile .json file)")
    if extras:
        raise DermisError(f"{source}: [skin] '{extras[0]}' does not apply to a profile file")
    base = Path(base_dir).resolve()
    path = (base / profile).resolve()
    if not path.is_relative_to(base):
        raise DermisError(f"{source}: [skin] profile file '{profile}' lies outside the scene's folder {base}")
    if not path.is_file():
        raise DermisError(f"{source}: [skin] profile file '{profile}' does not exist")
    from dermis.profiles.profile_json import read_profile_json

    radial, gaussians = read_profile_json(path)
    if gaussians is not None and (k is None or k == gaussians.k):
        return gaussians
    from dermis.profiles.fit import fit_sum_of_gaussians

    return fit_sum_of_gaussians(radial, k or 6, name=path.stem).profile
