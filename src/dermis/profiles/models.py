"""From skin parameters to an RGB diffusion profile: the dispatch among the profile models.

Every model yields a :class:`RadialProfile`: R(r) per linear-sRGB channel (1/mm^2, per unit
power entering the skin) on a log-spaced radius grid, and the total diffuse reflectance per
channel (its integral over the plane). The models:

    dipole     Jensen et al. 2001 per layer (a slab's lower boundary ignored), layers combined
    multipole  Donner & Jensen 2005 per layer, layers combined (the model of D&J 2006)
    pbd        photon beam diffusion (Habel et al. 2013) per layer, layers combined  [default]
    burley     Christensen & Burley 2015, its albedo and width matched to the pbd profile
    mc         the MCML Monte Carlo reference, per wavelength (slow)
    deon       d'Eon et al. 2007's six Gaussians (not spectral; each channel integrates to 1)

Spectral models run on 400-700 nm (spectral.py), combine the epidermis and dermis in the
frequency domain (layers.py) and convert to linear sRGB with the CIE observer.

Accuracy of the layered pbd model against the Monte Carlo, fair skin (tests/test_profiles_layers.py):
total reflectance within 3 %; R(r) within ~11 % from 0.05 to 1 mm; 15-40 % LOW from 2 to 5 mm
(a 0.25 mm epidermis is thinner than a transport mean free path, and combining it with the
dermis in the frequency domain loses lateral transport). With isotropic scattering (the default,
see spectral.py) single scattering makes R(r) ~ 1/r within ~0.02 mm of the entry point; the
Gaussian fit resolves that only down to its grid step. The multipole and dipole models get the
totals within ~10 % but the shape wrong by up to 60 % below 0.2 mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from dermis.errors import DermisError
from dermis.numpy_compat import trapezoid
from dermis.profiles.burley import burley_mean_free_path_for_mean_radius, burley_reflectance
from dermis.profiles.gaussians import SumOfGaussians, deon_skin
from dermis.profiles.hankel import LogRadialGrid
from dermis.profiles.layers import LayerResponse, combine_layers
from dermis.profiles.medium import Layer
from dermis.profiles.multipole import multipole_profiles
from dermis.profiles.photon_beam_diffusion import pbd_slab_profiles
from dermis.profiles.spectral import DEFAULT_WAVELENGTHS_NM, SkinParameters, skin_layers, spectrum_to_linear_srgb_matrix

MODELS: tuple[str, ...] = ("dipole", "multipole", "pbd", "burley", "mc", "deon")

#: FFTLog grid of the layer combination (accurate to ~1e-8 of the peak, tests/test_profiles_layers.py)
DIFFUSION_GRID = LogRadialGrid(1e-6, 1e3, 1024)
#: Radii at which the slab models are evaluated before interpolation onto DIFFUSION_GRID
#: (the profiles are smooth in log r; 50 points per decade keep the spline error below 1e-4).
EVALUATION_RADII_MM = np.geomspace(1e-5, 300.0, 376)
#: Radii kept in a RadialProfile of a diffusion model
OUTPUT_RANGE_MM = (1e-4, 100.0)
SLAB_BEAM_SAMPLES = 32


@dataclass(frozen=True, eq=False)
class RadialProfile:
    """R(r) in linear sRGB: ``radius_mm`` (N,), ``rgb_per_mm2`` (N, 3), totals (3,).

    ``spectral`` optionally holds {"wavelength_nm", "total_reflectance"} of a spectral model and
    ``standard_error_rgb_per_mm2`` the Monte Carlo's standard error per radius.
    """

    radius_mm: np.ndarray
    rgb_per_mm2: np.ndarray
    total_reflectance_rgb: np.ndarray
    model: str
    name: str = "custom"
    spectral: dict = field(default_factory=dict)
    standard_error_rgb_per_mm2: np.ndarray | None = None

    def evaluate(self, radius_mm) -> np.ndarray:
        """R at any radii, (..., 3): linear in ln r between samples, the first sample's value
        below the grid, 0 beyond it."""
        r = np.asarray(radius_mm, dtype=np.float64)
        log_r = np.log(np.maximum(r, self.radius_mm[0]))
        log_grid = np.log(self.radius_mm)
        out = np.stack([np.interp(log_r, log_grid, self.rgb_per_mm2[:, c], right=0.0) for c in range(3)], -1)
        return out

    def mean_radius_mm(self) -> np.ndarray:
        """integral 2 pi r^2 R dr / integral 2 pi r R dr per channel (on the profile's samples)."""
        r = self.radius_mm[:, None]
        first = trapezoid(2 * np.pi * r * r * self.rgb_per_mm2, self.radius_mm, axis=0)
        zeroth = trapezoid(2 * np.pi * r * self.rgb_per_mm2, self.radius_mm, axis=0)
        return first / np.where(zeroth > 0, zeroth, 1.0)


def _to_grid(values: np.ndarray, radius_mm: np.ndarray, grid: LogRadialGrid) -> np.ndarray:
    """Spline positive samples in (ln r, ln R) onto the FFTLog grid: a power law through the first
    two samples below them, zero beyond them."""
    if np.any(values < 0):
        raise ValueError("log-spline interpolation needs non-negative profiles")
    log_r = np.log(radius_mm)
    log_values = np.log(np.maximum(values, 1e-300))
    spline = CubicSpline(log_r, log_values, axis=0, extrapolate=True)
    target = np.log(grid.radius_mm)
    out = np.exp(spline(np.clip(target, log_r[0], log_r[-1])))
    out[target > log_r[-1]] = 0.0
    below = target < log_r[0]
    if np.any(below):
        slope = (log_values[1] - log_values[0]) / (log_r[1] - log_r[0])
        out[below] = np.exp(log_values[0] + slope * (target[below, None] - log_r[0]))
    return out


def _boundary_indices(layers):
    """eta = n_layer / n_neighbour above and below each layer (air around the stack)."""
    n = [layer.medium.n for layer in layers]
    above = [n[0] / 1.0] + [n[i] / n[i - 1] for i in range(1, len(n))]
    below = [n[i] / n[i + 1] for i in range(len(n) - 1)] + [n[-1] / 1.0]
    return above, below


def layered_diffusion_reflectance(layers: list[Layer], model: str, grid: LogRadialGrid = DIFFUSION_GRID):
    """R(r, lambda) on ``grid`` and R_d(lambda) of a stack of layers (top first) by a diffusion model.

    ``model``: "pbd" (photon beam diffusion per slab, single scattering in the top layer),
    "multipole" (Donner & Jensen 2005 per slab) or "dipole" (one dipole per slab).
    """
    if model not in ("pbd", "multipole", "dipole"):
        raise DermisError(f"'{model}' is not a layered diffusion model (pbd, multipole, dipole)")
    # PBD is costly: evaluate it on EVALUATION_RADII_MM and spline onto the grid; the closed-form
    # multipoles are evaluated on the grid itself (they may dip below zero: no log spline)
    radius = EVALUATION_RADII_MM if model == "pbd" else grid.radius_mm
    above, below = _boundary_indices(layers)
    responses = []
    for i, layer in enumerate(layers):
        medium, thickness = layer.medium, layer.thickness_mm
        top_layer, slab = i == 0, not layer.semi_infinite
        if model == "pbd":
            down = pbd_slab_profiles(radius, medium, thickness, above[i], below[i], single_scattering=top_layer,
                                     beam_samples=SLAB_BEAM_SAMPLES if slab else 64)
            fields = {"reflectance_down": down.reflectance, "ballistic": down.ballistic}
            if slab:
                up = pbd_slab_profiles(radius, medium, thickness, above[i], below[i], from_below=True,
                                       single_scattering=False, beam_samples=SLAB_BEAM_SAMPLES)
                fields.update(transmittance_down=down.transmittance, reflectance_up=up.reflectance,
                              transmittance_up=up.transmittance)
        else:
            pairs = 0 if model == "dipole" else None
            r_down, t_down = multipole_profiles(radius, medium, thickness, above[i], below[i], pairs)
            fields = {"reflectance_down": r_down, "ballistic": np.zeros(medium.wavelength_count)}
            if slab:
                r_up, t_up = multipole_profiles(radius, medium, thickness, above[i], below[i], pairs, from_below=True)
                fields.update(transmittance_down=t_down, reflectance_up=r_up, transmittance_up=t_up)
        shaped = {k: v if k == "ballistic" else np.reshape(v, (radius.size, -1)) for k, v in fields.items()}
        if model == "pbd":
            shaped = {k: v if k == "ballistic" else _to_grid(np.maximum(v, 0.0), radius, grid)
                      for k, v in shaped.items()}
        responses.append(LayerResponse(**shaped))
    return combine_layers(responses, grid)


def _channel_matrix(wavelength_nm, illuminant):
    """Spectral samples -> linear sRGB, or the identity when the 'wavelengths' are the RGB channels."""
    return np.eye(3) if wavelength_nm is None else spectrum_to_linear_srgb_matrix(wavelength_nm, illuminant)


def _spectral_to_profile(radius, spectral_values, spectral_totals, wavelength_nm, illuminant, model, name,
                         spectral_errors=None) -> RadialProfile:
    matrix = _channel_matrix(wavelength_nm, illuminant)
    # Saturated reds far from the entry point can fall (by < 1e-5 of the peak) outside the sRGB
    # gamut: clip those negative channel values to 0
    rgb = np.maximum(spectral_values @ matrix.T, 0.0)
    errors = None if spectral_errors is None else np.sqrt((spectral_errors**2) @ (matrix**2).T)
    spectral = {} if wavelength_nm is None else {"wavelength_nm": np.asarray(wavelength_nm, dtype=float),
                                                 "total_reflectance": np.asarray(spectral_totals, dtype=float)}
    return RadialProfile(radius, rgb, matrix @ spectral_totals, model, name, spectral, errors)


def deon_profile() -> RadialProfile:
    """d'Eon et al. 2007's six Gaussians as a RadialProfile (each channel integrates to 1)."""
    gaussians = deon_skin()
    radius = DIFFUSION_GRID.radius_mm
    keep = (radius >= OUTPUT_RANGE_MM[0]) & (radius <= OUTPUT_RANGE_MM[1])
    return RadialProfile(radius[keep], gaussians.evaluate(radius[keep]), gaussians.total_reflectance, "deon", "deon")


def gaussians_profile(gaussians: SumOfGaussians, model: str = "gaussians") -> RadialProfile:
    """Any SumOfGaussians as a RadialProfile."""
    radius = DIFFUSION_GRID.radius_mm
    keep = (radius >= OUTPUT_RANGE_MM[0]) & (radius <= OUTPUT_RANGE_MM[1])
    return RadialProfile(radius[keep], gaussians.evaluate(radius[keep]), gaussians.total_reflectance, model,
                         gaussians.name)


def skin_profile(parameters: SkinParameters, model: str = "pbd", *, wavelength_nm=DEFAULT_WAVELENGTHS_NM,
                 illuminant: str = "D65", photons: int = 100_000, seed: int = 0, progress=False,
                 name: str = "skin") -> RadialProfile:
    """The RGB diffusion profile of skin described by ``parameters`` under ``model`` (see MODELS).

    ``photons`` (per wavelength), ``seed`` and ``progress`` apply to the Monte Carlo only.
    """
    if model not in MODELS:
        raise DermisError(f"unknown profile model '{model}' (known: {', '.join(MODELS)})")
    if model == "deon":
        return deon_profile()
    wavelength = np.asarray(wavelength_nm, dtype=np.float64)
    if model == "burley":
        return burley_skin_profile(parameters, wavelength_nm=wavelength, illuminant=illuminant, name=name)
    return medium_profile(skin_layers(parameters, wavelength), model, wavelength_nm=wavelength, illuminant=illuminant,
                          photons=photons, seed=seed, progress=progress, name=name)


def medium_profile(layers: list[Layer], model: str = "pbd", *, wavelength_nm=None, illuminant: str = "D65",
                   photons: int = 100_000, seed: int = 0, progress=False, name: str = "medium") -> RadialProfile:
    """The RGB profile of a stack of layers (top first) given by its coefficients.

    ``wavelength_nm``: the wavelengths of the coefficients' entries (integrated to linear sRGB),
    or None when the coefficients have three entries, the linear-sRGB channels themselves.
    ``model``: dipole, multipole, pbd, burley (matched to pbd) or mc.
    """
    if model not in ("dipole", "multipole", "pbd", "burley", "mc"):
        raise DermisError(f"model '{model}' does not take a medium (use dipole, multipole, pbd, burley, mc)")
    wavelength = None if wavelength_nm is None else np.asarray(wavelength_nm, dtype=np.float64)
    count = layers[0].medium.wavelength_count
    if any(layer.medium.wavelength_count != count for layer in layers) or (wavelength is None and count != 3) or (
            wavelength is not None and wavelength.size != count):
        raise DermisError("every layer needs one coefficient per wavelength (or 3, the RGB channels)")
    if model == "burley":
        reference = medium_profile(layers, "pbd", wavelength_nm=wavelength, illuminant=illuminant, name=name)
        return burley_matched_profile(reference, name)
    if model == "mc":
        return _monte_carlo_profile(layers, wavelength, illuminant, photons, seed, progress, name)
    result = layered_diffusion_reflectance(layers, model)
    radius = result.grid.radius_mm
    keep = (radius >= OUTPUT_RANGE_MM[0]) & (radius <= OUTPUT_RANGE_MM[1])
    return _spectral_to_profile(radius[keep], result.reflectance[keep], result.total_reflectance, wavelength,
                                illuminant, model, name)


def burley_skin_profile(parameters: SkinParameters, *, wavelength_nm=DEFAULT_WAVELENGTHS_NM, illuminant="D65",
                        name: str = "skin", reference: RadialProfile | None = None) -> RadialProfile:
    """Christensen-Burley per RGB channel, with albedo = the pbd profile's total reflectance and
    the mean free path chosen so that the mean radius equals the pbd profile's."""
    if reference is None:
        reference = skin_profile(parameters, "pbd", wavelength_nm=wavelength_nm, illuminant=illuminant, name=name)
    return burley_matched_profile(reference, name)


def burley_matched_profile(reference: RadialProfile, name: str) -> RadialProfile:
    """Christensen-Burley per RGB channel with the total reflectance and mean radius of ``reference``."""
    albedo = np.clip(reference.total_reflectance_rgb, 1e-6, 1.0)
    mean_free_path = burley_mean_free_path_for_mean_radius(albedo, reference.mean_radius_mm())
    radius = reference.radius_mm
    return RadialProfile(radius, burley_reflectance(radius, albedo, mean_free_path), albedo.copy(), "burley", name,
                         {"mean_free_path_mm": mean_free_path})


def burley_artist_profile(albedo_rgb, mean_free_path_mm_rgb, name: str = "burley") -> RadialProfile:
    """The artist-facing Christensen-Burley profile (Christensen & Burley 2015): surface albedo A and
    mean free path l per RGB channel, no physical parameters. Its integral over the plane is A."""
    albedo = np.asarray(albedo_rgb, np.float64).reshape(3)
    mfp = np.asarray(mean_free_path_mm_rgb, np.float64).reshape(3)
    if np.any(albedo <= 0) or np.any(albedo > 1) or np.any(mfp <= 0) or not np.all(np.isfinite(mfp)):
        raise DermisError(f"burley: albedo must be in (0, 1] and mean free path > 0 mm, got {albedo.tolist()}, {mfp.tolist()}")
    radius = np.geomspace(1e-3, max(60.0, 40.0 * mfp.max()), 400)
    return RadialProfile(radius, burley_reflectance(radius, albedo, mfp), albedo.copy(), "burley", name,
                         {"mean_free_path_mm": mfp})


MONTE_CARLO_BIN_EDGES_MM = np.concatenate([[0.0], np.geomspace(0.01, 40.0, 73)])


def monte_carlo_spectral(layers, photons: int, seed: int = 0, progress=False):
    """MCML per coefficient entry (wavelength or RGB channel) of ``layers`` on MONTE_CARLO_BIN_EDGES_MM.

    Returns (R (B, L) 1/mm^2, its standard error (B, L), R_d (L,), R_d's standard error (L,)); the
    entry i runs with seed ``seed + 7919 i``. ``progress``: False, True (a tqdm bar) or a bar.
    """
    from dermis.profiles.monte_carlo import monte_carlo_reflectance

    count = layers[0].medium.wavelength_count
    bar = progress
    if progress is True:
        from tqdm import tqdm

        bar = tqdm(total=int(photons) * count, unit="photon", unit_scale=True, desc="Monte Carlo")
    values, errors, totals, total_errors = [], [], [], []
    try:
        for i in range(count):
            stack = [Layer(layer.medium.select([i]), layer.thickness_mm) for layer in layers]
            result = monte_carlo_reflectance(stack, photons, MONTE_CARLO_BIN_EDGES_MM, seed=seed + 7919 * i,
                                             progress=bar)
            values.append(result.reflectance_per_mm2)
            errors.append(result.standard_error_per_mm2)
            totals.append(result.total_reflectance)
            total_errors.append(result.total_reflectance_standard_error)
    finally:
        if progress is True:
            bar.close()
    return np.array(values).T, np.array(errors).T, np.array(totals), np.array(total_errors)


def monte_carlo_bin_radii_mm() -> np.ndarray:
    """The radius a Monte Carlo bin's mean is placed at: half the first edge, then the geometric mean."""
    edges = MONTE_CARLO_BIN_EDGES_MM
    return np.concatenate([[0.5 * edges[1]], np.sqrt(edges[1:-1] * edges[2:])])


def monte_carlo_table_profile(values, errors, totals, wavelength, illuminant="D65", name="mc") -> RadialProfile:
    """A RadialProfile of spectral Monte Carlo bins (monte_carlo_spectral's first three results)."""
    return _spectral_to_profile(monte_carlo_bin_radii_mm(), np.asarray(values), np.asarray(totals), wavelength,
                                illuminant, "mc", name, np.asarray(errors))


def _monte_carlo_profile(layers, wavelength, illuminant, photons, seed, progress, name) -> RadialProfile:
    values, errors, totals, _ = monte_carlo_spectral(layers, photons, seed, progress)
    return monte_carlo_table_profile(values, errors, totals, wavelength, illuminant, name)
