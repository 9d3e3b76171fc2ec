"""Diffusion profiles from physics (no GL): sum-of-Gaussians, dipole, multipole, photon beam
diffusion, Christensen-Burley, the spectral skin model and a Monte Carlo reference.

    skin parameters (spectral.py, presets.py)
      -> absorption / scattering per wavelength -> layers (medium.py)
      -> per-layer profiles (dipole.py, multipole.py, photon_beam_diffusion.py)
      -> combined in the frequency domain (layers.py, hankel.py)
      -> linear sRGB profile (models.py) -> K Gaussians (fit.py)
      -> the renderer (scene_skin.resolve_skin_profile), the CLI (cli.py), JSON (profile_json.py)
    monte_carlo.py (MCML in numba) is the reference the models are tested against; its tables
    for the shipped presets (monte_carlo_tables.py, data/) are the shape those presets render with.

Heavy modules (scipy, numba, colour-science) load on first use of their names.
"""

from importlib import import_module

from dermis.profiles.gaussians import SumOfGaussians, deon_skin, gaussian_2d
from dermis.profiles.presets import PRESETS, SKIN_PRESETS, skin_preset

_LAZY = {
    "resolve_skin_profile": "scene_skin",
    "physical_gaussians": "scene_skin",
    "SkinParameters": "spectral",
    "skin_layers": "spectral",
    "spectrum_to_linear_srgb_matrix": "spectral",
    "MODELS": "models",
    "RadialProfile": "models",
    "skin_profile": "models",
    "deon_profile": "models",
    "layered_diffusion_reflectance": "models",
    "fit_sum_of_gaussians": "fit",
    "GaussianFit": "fit",
    "relative_l2_error": "fit",
    "Medium": "medium",
    "Layer": "medium",
    "dipole_reflectance": "dipole",
    "dipole_total_reflectance": "dipole",
    "multipole_profiles": "multipole",
    "pbd_reflectance": "photon_beam_diffusion",
    "pbd_slab_profiles": "photon_beam_diffusion",
    "burley_reflectance": "burley",
    "LogRadialGrid": "hankel",
    "combine_layers": "layers",
    "LayerResponse": "layers",
    "monte_carlo_reflectance": "monte_carlo",
    "MonteCarloResult": "monte_carlo",
    "MonteCarloTable": "monte_carlo_tables",
    "shipped_table": "monte_carlo_tables",
    "read_profile_json": "profile_json",
}

__all__ = ["SumOfGaussians", "deon_skin", "gaussian_2d", "PRESETS", "SKIN_PRESETS", "skin_preset", *_LAZY]


def __getattr__(name):
    if name in _LAZY:
        value = getattr(import_module(f"dermis.profiles.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'dermis.profiles' has no attribute '{name}'")
