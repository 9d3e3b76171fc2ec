"""Named skin presets, fitted to measured skin reflectance.

Each spectral preset is a Donner & Jensen 2006 skin (spectral.py: 0.25 mm epidermis, 75 %
oxygenated blood) whose melanin fraction C_m, eumelanin share beta_m and blood fraction C_h
were fitted (benchmarks/fit_skin_presets.py) so that its total reflectance matches its measured
counterpart (measured_skin.py, MEASURED_COUNTERPARTS below) per linear-sRGB channel:

    fair, dark       the ColorChecker's "light skin" and "dark skin" patches
    asian            the NIST forearms of the "intermediate" ITA category (pheomelanin only,
                     beta_m = 0, as Donner & Jensen's Asian skin)
    very-light, light, intermediate, tan, brown
                     the mean NIST forearm of each skin-colour category of Del Bino et al.
                     2006 (Individual Typology Angle; the Fitzpatrick types' usual proxy). The
                     sixth category, "dark", has no NIST subject: its preset is ``dark``.

Why the earlier presets were far too dark: the triples (0.005, 0.7, 0.005), (0.15, 0, 0.01) and
(0.5, 0.7, 0.05) used melanosome volume fractions (Jacques 1998: 1.3-6.3 % light, 11-16 %
moderately pigmented, 18-43 % dark skin) as if they filled the whole 0.25 mm epidermis. Those
fractions hold in the melanosome-bearing basal layer, some tens of micrometres thick; averaged
over 0.25 mm they are several times smaller. C_m = 0.5 gave a melanin optical depth of
0.5 x 50/mm x 0.25 mm = 6 at 550 nm, and about 2 % reflectance. The coefficient formulas are
right (Jacques' 6.6e11 lambda^-3.33 /cm and 0.244 + 85.3 e^(-(lambda - 154)/66.2) /cm are
6.6e10 and 0.0244 + 8.53 e^(...) /mm) and so is the layering of the totals (Monte Carlo agrees
within 3 %, tests/test_profiles_layers.py).

Measured (benchmarks/RESULTS.md, tests/test_profiles_measured.py): every channel of every
preset within 15 % of its counterpart except ``fair``'s red, 19 % low: the "light skin" paint
rises more steeply from 580 to 700 nm than any C_m, beta_m, C_h of the two-layer model reaches
(0.71 at 700 nm, above even the lightest NIST forearms' 0.65 with the specular part); a fit that
balances the channels leaves red 14 % low and green and blue 22 % high instead. Every fit chose
beta_m = 0 (pheomelanin's steeper lambda^-4.75) and little blood: the parameters are effective
values of this model, not measurements of the skins' chromophores.

``deon`` is the six-Gaussian table of d'Eon, Luebke & Enderton 2007 (gaussians.py), a fitted
profile rather than skin parameters.
"""

from __future__ import annotations

from dermis.errors import DermisError
from dermis.profiles.spectral import SkinParameters

# (C_m, beta_m, C_h), fitted by benchmarks/fit_skin_presets.py
_FITTED = {
    "fair": (0.0151, 0.000, 0.0024),
    "asian": (0.0251, 0.000, 0.0007),
    "dark": (0.1349, 0.000, 0.0000),
    "very-light": (0.0085, 0.000, 0.0023),
    "light": (0.0133, 0.000, 0.0033),
    "intermediate": (0.0251, 0.000, 0.0007),  # the same fit as asian (the fit chose beta_m = 0 for all)
    "tan": (0.0468, 0.000, 0.0000),
    "brown": (0.0862, 0.000, 0.0000),
}

SKIN_PRESETS: dict[str, SkinParameters] = {
    name: SkinParameters(melanin_fraction=cm, melanin_blend=blend, hemoglobin_fraction=ch)
    for name, (cm, blend, ch) in _FITTED.items()
}

#: The measured skin each preset was fitted to: ("colorchecker", patch) or ("nist", ITA category)
MEASURED_COUNTERPARTS: dict[str, tuple[str, str]] = {
    "fair": ("colorchecker", "light skin"),
    "asian": ("nist", "intermediate"),
    "dark": ("colorchecker", "dark skin"),
    "very-light": ("nist", "very_light"),
    "light": ("nist", "light"),
    "intermediate": ("nist", "intermediate"),
    "tan": ("nist", "tan"),
    "brown": ("nist", "brown"),
}

#: Every preset name: d'Eon's table and the spectral skin types.
PRESETS: tuple[str, ...] = ("deon",) + tuple(SKIN_PRESETS)


def skin_preset(name: str) -> SkinParameters:
    """The SkinParameters of a spectral preset (see SKIN_PRESETS)."""
    key = str(name).strip().lower()
    if key not in SKIN_PRESETS:
        if key == "deon":
            raise DermisError("preset 'deon' is a fitted Gaussian table, not skin parameters (use model deon)")
        raise DermisError(f"unknown skin preset '{name}' (known: {', '.join(PRESETS)})")
    return SKIN_PRESETS[key]
