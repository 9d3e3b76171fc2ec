"""The profile JSON file written by ``dermis profile --json`` and read by a scene's [skin] section.

    {
      "format": "dermis-profile", "version": 1,
      "model": "pbd", "name": "fair", "parameters": {...} | null, "illuminant": "D65",
      "units": {...},
      "radii_mm": [N], "profile_rgb": [[r, g, b] x N],          R(r), 1/mm^2, linear sRGB
      "total_reflectance_rgb": [3],                              integral of R over the plane
      "fit": null | {"k": K, "variances_mm2": [K], "weights_rgb": [[r, g, b] x K],
                     "relative_error_rgb": [3], "relative_error": e, "total_reflectance_rgb": [3]}
    }

Files are written atomically: to a temporary name in the same folder, then renamed over the target.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.images import atomic_write
from dermis.profiles.gaussians import SumOfGaussians

FORMAT = "dermis-profile"
VERSION = 1
OUTPUT_RADII_MM = np.geomspace(1e-3, 60.0, 240)


def write_atomic(path, write) -> None:
    """Call ``write(file_object)`` on a temporary file beside ``path``, then rename it to ``path``."""

    def to_file(temporary):
        with open(temporary, "wb") as stream:
            write(stream)

    atomic_write(path, to_file)


def profile_document(profile, fit=None, parameters: dict | None = None, illuminant: str | None = None) -> dict:
    """The JSON document of a RadialProfile (and its GaussianFit)."""
    if profile.model == "mc":
        radii = profile.radius_mm
    else:
        top = min(float(profile.radius_mm[-1]), OUTPUT_RADII_MM[-1])
        radii = OUTPUT_RADII_MM[OUTPUT_RADII_MM <= top]
    document = {
        "format": FORMAT,
        "version": VERSION,
        "model": profile.model,
        "name": profile.name,
        "parameters": parameters,
        "illuminant": illuminant,
        "units": {"radii_mm": "mm", "profile_rgb": "1/mm^2 per unit power entering the skin, linear sRGB",
                  "variances_mm2": "mm^2", "weights_rgb": "share of the total diffuse reflectance"},
        "radii_mm": [float(r) for r in radii],
        "profile_rgb": np.asarray(profile.evaluate(radii), dtype=float).tolist(),
        "total_reflectance_rgb": [float(v) for v in profile.total_reflectance_rgb],
        "fit": None,
    }
    if profile.standard_error_rgb_per_mm2 is not None:
        document["standard_error_rgb"] = np.asarray(profile.standard_error_rgb_per_mm2, dtype=float).tolist()
    if fit is not None:
        document["fit"] = {
            "k": fit.profile.k,
            "variances_mm2": fit.profile.variances_mm2.tolist(),
            "weights_rgb": fit.profile.weights.tolist(),
            "relative_error_rgb": [float(v) for v in fit.relative_error_rgb],
            "relative_error": fit.relative_error,
            "total_reflectance_rgb": [float(v) for v in fit.total_reflectance_rgb],
        }
    return document


def write_profile_json(path, document: dict) -> None:
    text = json.dumps(document, indent=1).encode()
    write_atomic(path, lambda stream: stream.write(text))


def _vector(document, key, path, length=None):
    value = document.get(key)
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise DermisError(f"{path}: '{key}' must be an array of numbers") from None
    if array.ndim == 0 or (length is not None and array.shape[-1] != length) or not np.all(np.isfinite(array)):
        raise DermisError(f"{path}: '{key}' must be a finite array" + (f" of {length}" if length else ""))
    return array


def read_profile_json(path):
    """(RadialProfile, SumOfGaussians | None) from a file written by ``dermis profile --json``."""
    from dermis.profiles.models import RadialProfile

    path = Path(path)
    try:
        document = json.loads(path.read_text())
    except OSError as exc:
        raise DermisError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DermisError(f"{path}: not a JSON file ({exc})") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise DermisError(f"{path}: not a dermis profile (write one with 'dermis profile --json')")
    if document.get("version") != VERSION:
        raise DermisError(f"{path}: profile version {document.get('version')!r} is not supported (want {VERSION})")
    radii = _vector(document, "radii_mm", path)
    rgb = _vector(document, "profile_rgb", path, 3)
    totals = _vector(document, "total_reflectance_rgb", path, 3)
    if radii.ndim != 1 or rgb.shape != (radii.size, 3) or radii.size < 2 or np.any(np.diff(radii) <= 0) or radii[0] <= 0:
        raise DermisError(f"{path}: 'radii_mm' must increase from > 0 and match 'profile_rgb' (N x 3)")
    name = str(document.get("name") or path.stem)
    profile = RadialProfile(radii, rgb, totals, str(document.get("model", "file")), name)
    gaussians = None
    fit = document.get("fit")
    if fit is not None:
        if not isinstance(fit, dict):
            raise DermisError(f"{path}: 'fit' must be an object or null")
        variances = _vector(fit, "variances_mm2", path)
        weights = _vector(fit, "weights_rgb", path, 3)
        try:
            gaussians = SumOfGaussians(variances, weights, name)
        except DermisError as exc:
            raise DermisError(f"{path}: {exc}") from None
    return profile, gaussians
