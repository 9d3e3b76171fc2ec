"""A layered medium given by its optical coefficients: ``dermis profile --medium FILE`` and a
scene's ``[skin] profile = "medium"`` with ``[[skin.layer]]`` tables.

    # layers.toml (or the same keys as JSON: {"layer": [{...}, {...}]})
    [[layer]]                        # top layer first
    sigma_a = [0.30, 0.60, 1.2]      # absorption, 1/mm: one number, or R,G,B
    sigma_s_reduced = [2.5, 3.0, 3.5]  # sigma_s' = sigma_s (1 - g), 1/mm  (or sigma_s with g)
    g = 0.8                          # Henyey-Greenstein anisotropy [0]
    eta = 1.4                        # refractive index [1.4]
    thickness_mm = 0.1               # omitted or "inf" for the semi-infinite bottom layer
    [[layer]]
    mfp_mm = [1.2, 0.6, 0.3]         # or: transport mean free path 1 / sigma_t' (mm) ...
    albedo = [0.995, 0.98, 0.95]     #     ... and reduced albedo sigma_s' / sigma_t'
    eta = 1.4

Each coefficient has 1 or C values (C = 3: linear-sRGB channels, or C = the length of a top-level
``wavelength_nm = [...]`` list: then the profile is spectral and is integrated to sRGB as the
skin model's, spectral.py). Only the last layer may be semi-infinite; a stack whose last layer
has a thickness is a slab over air (transmitted light is lost).
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.profiles.medium import Layer, Medium

LAYER_KEYS = ("sigma_a", "sigma_s_reduced", "sigma_s", "g", "eta", "thickness_mm", "mfp_mm", "albedo")


def _values(layer: dict, key: str, where: str, channels: int) -> np.ndarray:
    value = layer[key]
    items = value if isinstance(value, list) else [value]
    if not items or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in items):
        raise DermisError(f"{where}: {key} must be a number or a list of numbers, got {value!r}")
    array = np.array(items, dtype=np.float64)
    if array.size == 1:
        array = np.repeat(array, channels)
    if array.size != channels:
        raise DermisError(f"{where}: {key} has {array.size} values; give 1 or {channels}")
    if not np.all(np.isfinite(array)) or np.any(array < 0):
        raise DermisError(f"{where}: {key} must be finite and >= 0")
    return array


def _scalar(layer: dict, key: str, where: str, default: float) -> float:
    value = layer.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise DermisError(f"{where}: {key} must be a number, got {value!r}")
    return float(value)


def _layer(layer, where: str, channels: int, last: bool) -> Layer:
    if not isinstance(layer, dict):
        raise DermisError(f"{where}: a layer must be a table of coefficients")
    unknown = [key for key in layer if key not in LAYER_KEYS]
    if unknown:
        raise DermisError(f"{where}: unknown key '{unknown[0]}' (known: {', '.join(LAYER_KEYS)})")
    g = _scalar(layer, "g", where, 0.0)
    n = _scalar(layer, "eta", where, 1.4)
    if not -1.0 < g < 1.0:
        raise DermisError(f"{where}: g must lie in (-1, 1), got {g}")
    if not 1.0 <= n <= 3.0:
        raise DermisError(f"{where}: eta must lie in [1, 3], got {n}")
    given = {key for key in ("sigma_a", "sigma_s_reduced", "sigma_s", "mfp_mm", "albedo") if key in layer}
    if given == {"mfp_mm", "albedo"}:
        mfp = _values(layer, "mfp_mm", where, channels)
        albedo = _values(layer, "albedo", where, channels)
        if np.any(mfp <= 0) or np.any(albedo > 1):
            raise DermisError(f"{where}: mfp_mm must be > 0 and albedo in [0, 1]")
        sigma_a, reduced = (1.0 - albedo) / mfp, albedo / mfp  # sigma_t' = 1 / mfp, alpha' = sigma_s' / sigma_t'
        medium = Medium.from_reduced(sigma_a, reduced, g, n)
    elif given in ({"sigma_a", "sigma_s_reduced"}, {"sigma_a", "sigma_s"}):
        sigma_a = _values(layer, "sigma_a", where, channels)
        if "sigma_s" in given:
            medium = Medium(sigma_a, _values(layer, "sigma_s", where, channels), g, n)
        else:
            medium = Medium.from_reduced(sigma_a, _values(layer, "sigma_s_reduced", where, channels), g, n)
    else:
        raise DermisError(f"{where}: give sigma_a with sigma_s_reduced (or sigma_s and g), or mfp_mm with albedo")
    thickness = layer.get("thickness_mm", "inf")
    if isinstance(thickness, str) and thickness.strip().lower() in ("inf", "infinite"):
        thickness = np.inf
    if isinstance(thickness, bool) or not isinstance(thickness, (int, float)) or not thickness > 0:
        raise DermisError(f"{where}: thickness_mm must be a number > 0 (mm) or \"inf\", got {thickness!r}")
    if np.isinf(thickness) and not last:
        raise DermisError(f"{where}: only the last layer may be semi-infinite (give thickness_mm)")
    return Layer(medium, float(thickness))


def layers_from_description(description, source: str) -> tuple[list[Layer], np.ndarray | None]:
    """([Layer], wavelength_nm or None for RGB channels) of a medium description (module docstring)."""
    if not isinstance(description, dict):
        raise DermisError(f"{source}: a medium must be a table with a 'layer' list")
    unknown = [key for key in description if key not in ("layer", "wavelength_nm")]
    if unknown:
        raise DermisError(f"{source}: unknown key '{unknown[0]}' (known: layer, wavelength_nm)")
    layers = description.get("layer")
    if not isinstance(layers, list) or not layers:
        raise DermisError(f"{source}: a medium needs at least one [[layer]]")
    wavelength = description.get("wavelength_nm")
    if wavelength is not None:
        try:
            wavelength = np.asarray(wavelength, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise DermisError(f"{source}: wavelength_nm must be a list of numbers") from None
        if wavelength.size < 2 or np.any(np.diff(wavelength) <= 0) or wavelength[0] < 360 or wavelength[-1] > 830:
            raise DermisError(f"{source}: wavelength_nm must increase within 360-830 nm (at least 2 values)")
    channels = 3 if wavelength is None else wavelength.size
    last = len(layers) - 1
    stack = [_layer(layer, f"{source}: layer {i + 1}", channels, i == last) for i, layer in enumerate(layers)]
    return stack, wavelength


def read_medium_file(path) -> tuple[list[Layer], np.ndarray | None]:
    """The medium of a .toml or .json file (module docstring)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise DermisError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise DermisError(f"{path}: not a text file") from None
    try:
        if path.suffix.lower() == ".json":
            description = json.loads(text)
        elif path.suffix.lower() == ".toml":
            description = tomllib.loads(text)
        else:
            raise DermisError(f"{path}: a medium file must be .toml or .json")
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise DermisError(f"{path}: cannot parse ({exc})") from None
    return layers_from_description(description, str(path))


def medium_document(layers: list[Layer], wavelength_nm=None) -> dict:
    """The coefficients of a stack for a profile's JSON (1/mm, mm; 'inf' for semi-infinite)."""
    return {
        "channels": "linear sRGB" if wavelength_nm is None else "wavelength_nm",
        "wavelength_nm": None if wavelength_nm is None else [float(w) for w in wavelength_nm],
        "units": {"sigma_a": "1/mm", "sigma_s": "1/mm", "sigma_s_reduced": "1/mm", "thickness_mm": "mm"},
        "layer": [{"sigma_a": layer.medium.sigma_a_per_mm.tolist(), "sigma_s": layer.medium.sigma_s_per_mm.tolist(),
                   "sigma_s_reduced": layer.medium.reduced_sigma_s_per_mm.tolist(), "g": layer.medium.g,
                   "eta": layer.medium.n, "thickness_mm": "inf" if layer.semi_infinite else layer.thickness_mm}
                  for layer in layers],
    }
