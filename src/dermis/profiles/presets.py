"""Named skin presets, fitted to measured skin reflectance.

Each spectral preset is a Donner & Jensen 2006 skin (spectral.py: 0.25 mm epidermis, 75 %
oxygenated blood) whose melanin fraction C_m, eumelanin share beta_m and blood fraction C_h
were fitted (benchmarks/fit_skin_presets.py) so that the total reflectance of the Monte Carlo of
its layers (the profile it renders with: monte_carlo_tables.py) matches its measured counterpart
(measured_skin.py, MEASURED_COUNTERPARTS below) per linear-sRGB channel:

    very-light, light, intermediate, tan, brown
                     the mean NIST forearm of each skin-colour category of Del Bino et al.
                     2006 (Individual Typology Angle, ITA; the Fitzpatrick types' usual proxy)
    fair             = very-light: the lightest category (ITA > 55 deg)
    asian            = intermediate (pheomelanin only, beta_m = 0, as Donner & Jensen's Asian skin)
    dark             the ColorChecker's "dark skin" patch (ITA -39 deg: Del Bino's sixth category,
                     "dark", < -30 deg, which has no NIST subject)

Why ``fair`` is not the ColorChecker "light skin" patch (as it was first): by the same ITA that
classes the NIST subjects (computed with the same code), the patch is "light" skin (ITA 42.4 deg,
L* 66.2), not the lightest category, and it is redder than any measured category (a* 14.5
against 8.4-11.5 for the NIST forearms of every category, tan and brown included; its R/G in
linear sRGB, 1.81, is tan skin's at the lightness of light skin, whose R/G is 1.53; its body
reflectance reaches 0.71 at 700 nm, above even the lightest forearms' 0.65 WITH the specular part). No C_m, beta_m, C_h of the two-layer model
reaches it: with Jacques' baseline absorption (0.0244 /mm at 700 nm) and the dermis's sigma_s'
(2.2 /mm) pigment-free skin tops out at 0.59 at 700 nm (body reflectance), and the fits left red
14-19 % low or green and blue 22 % high; 98 % instead of 75 % oxygenation raises red by 0.6 %.
Dividing Jacques' baseline by 5 would lift red to the patch's (0.98 of it with the former fair
parameters) but leave green and blue 22-25 % high, and no source supports that baseline. The
patch stays in the comparison (benchmarks/RESULTS.md) as the paint it is.

Why the earlier presets were far too dark: the triples (0.005, 0.7, 0.005), (0.15, 0, 0.01) and
(0.5, 0.7, 0.05) used melanosome volume fractions (Jacques 1998: 1.3-6.3 % light, 11-16 %
moderately pigmented, 18-43 % dark skin) as if they filled the whole 0.25 mm epidermis. Those
fractions hold in the melanosome-bearing basal layer, some tens of micrometres thick; averaged
over 0.25 mm they are several times smaller. C_m = 0.5 gave a melanin optical depth of
0.5 x 50/mm x 0.25 mm = 6 at 550 nm, and about 2 % reflectance. The coefficient formulas are
right (Jacques' 6.6e11 lambda^-3.33 /cm and 0.244 + 85.3 e^(-(lambda - 154)/66.2) /cm are
6.6e10 and 0.0244 + 8.53 e^(...) /mm).

Measured (benchmarks/RESULTS.md, tests/test_profiles_measured.py): every channel of every
preset within 15 % of its counterpart. Every fit chose beta_m = 0 (pheomelanin's steeper
lambda^-4.75) and little blood: the parameters are effective values of this model, not
measurements of the skins' chromophores.

``deon`` is the six-Gaussian table of d'Eon, Luebke & Enderton 2007 (gaussians.py), a fitted
profile rather than skin parameters.
"""

from __future__ import annotations

from dermis.errors import DermisError
from dermis.profiles.spectral import SkinParameters

# (C_m, beta_m, C_h), fitted by benchmarks/fit_skin_presets.py
_FITTED = {
    "very-light": (0.0079, 0.000, 0.0027),
    "light": (0.0124, 0.000, 0.0034),
    "asian": (0.0224, 0.000, 0.0009),
    "tan": (0.0445, 0.000, 0.0000),
    "brown": (0.0787, 0.000, 0.0000),  # the ratio-space minimax (fit_skin_presets.py), see RESULTS
    "dark": (0.1200, 0.000, 0.0008),
}
_FITTED["fair"] = _FITTED["very-light"]  # the lightest measured category (module docstring)
_FITTED["intermediate"] = _FITTED["asian"]  # the same counterpart (the fit chose beta_m = 0 for both)
_ORDER = ("fair", "asian", "dark", "very-light", "light", "intermediate", "tan", "brown")

SKIN_PRESETS: dict[str, SkinParameters] = {
    name: SkinParameters(melanin_fraction=cm, melanin_blend=blend, hemoglobin_fraction=ch)
    for name, (cm, blend, ch) in ((n, _FITTED[n]) for n in _ORDER)
}

#: The measured skin each preset was fitted to: ("colorchecker", patch) or ("nist", ITA category)
MEASURED_COUNTERPARTS: dict[str, tuple[str, str]] = {
    "fair": ("nist", "very_light"),
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
