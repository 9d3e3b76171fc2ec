"""Named skin presets.

``fair``, ``asian`` and ``dark`` are the three skin types of Donner & Jensen 2006 (figure of the
spectral BSSRDF results), given as (C_m melanin fraction, beta_m eumelanin blend, C_h blood
fraction): fair (0.005, 0.7, 0.005), Asian (0.15, 0, 0.01), dark (0.5, 0.7, 0.05), with the
paper's epidermis of 0.25 mm and 75 % oxygenated blood. ``deon`` is the six-Gaussian table of
d'Eon, Luebke & Enderton 2007 (gaussians.py), a fitted profile rather than skin parameters.
"""

from __future__ import annotations

from dermis.errors import DermisError
from dermis.profiles.spectral import SkinParameters

SKIN_PRESETS: dict[str, SkinParameters] = {
    "fair": SkinParameters(melanin_fraction=0.005, melanin_blend=0.7, hemoglobin_fraction=0.005),
    "asian": SkinParameters(melanin_fraction=0.15, melanin_blend=0.0, hemoglobin_fraction=0.01),
    "dark": SkinParameters(melanin_fraction=0.5, melanin_blend=0.7, hemoglobin_fraction=0.05),
}

#: Every preset name: d'Eon's table and the spectral skin types.
PRESETS: tuple[str, ...] = ("deon",) + tuple(SKIN_PRESETS)


def skin_preset(name: str) -> SkinParameters:
    """The SkinParameters of a spectral preset (fair, asian, dark)."""
    key = str(name).strip().lower()
    if key not in SKIN_PRESETS:
        if key == "deon":
            raise DermisError("preset 'deon' is a fitted Gaussian table, not skin parameters (use model deon)")
        raise DermisError(f"unknown skin preset '{name}' (known: {', '.join(PRESETS)})")
    return SKIN_PRESETS[key]
