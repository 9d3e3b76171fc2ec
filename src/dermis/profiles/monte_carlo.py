"""Monte Carlo reference for light transport in layered media, following MCML (Wang, Jacques &
Zheng 1995, "MCML - Monte Carlo modeling of light transport in multi-layered tissues", Computer
Methods and Programs in Biomedicine 47, 131-146).

The rules of MCML: a normally incident pencil beam at the origin; step lengths -ln(xi)/mu_t in
dimensionless units that carry across layer boundaries; implicit capture (each
interaction deposits mu_a/mu_t of the photon's weight); Henyey-Greenstein scattering;
at every boundary the unpolarised Fresnel reflectance decides, all or none, whether the photon is
reflected or refracted by Snell's law; Russian roulette below weight 1e-4 with
survival chance 0.1; escapes through the top face scored in radial bins.

Convention shared with the diffusion models: photons are launched INSIDE the top layer with
weight 1, i.e. results are per unit power that entered the medium. MCML instead starts with
1 - R_sp; R_sp (normal-incidence Fresnel) is reported separately as ``specular_reflectance``.

Each photon escapes at most once, so per radial bin the per-photon scores are W or 0: the sum and
the sum of squares give the standard error of every bin. Photons run in independent streams of
a counter-based generator (SplitMix64, Steele, Lea & Flood 2014), so a result depends on the seed
and photon count only, not on the number of threads or the chunking used for the progress bar.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numba import njit, prange

from dermis.errors import DermisError
from dermis.profiles.medium import Layer

STREAM_PHOTONS = 2000  # photons per independent random stream
CHUNK_STREAMS = 32  # streams per kernel call (progress granularity)
ROULETTE_THRESHOLD = 1e-4  # MCML's W_th
ROULETTE_SURVIVAL = 0.1  # MCML's chance m

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX_1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX_2 = np.uint64(0x94D049BB133111EB)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2^-53


@njit(cache=True, inline="always")
def _mix64(z):
    """SplitMix64's output function (a bijective 64-bit hash)."""
    z = (z ^ (z >> np.uint64(30))) * _MIX_1
    z = (z ^ (z >> np.uint64(27))) * _MIX_2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def _splitmix64_uniform(state):
    """Next number in (0, 1] of the SplitMix64 stream held in state[0]."""
    state[0] += _GOLDEN
    return float((_mix64(state[0]) >> np.uint64(11)) + np.uint64(1)) * _TO_UNIT


@njit(cache=True, inline="always")
def _fresnel(n_incident, n_transmitted, cos_incident):
    """(unpolarised reflectance, cos of the refracted angle), MCML's RFresnel."""
    if n_incident == n_transmitted:
        return 0.0, cos_incident
    if cos_incident > 1.0 - 1e-12:
        r = (n_incident - n_transmitted) / (n_incident + n_transmitted)
        return r * r, cos_incident
    if cos_incident < 1e-6:
        return 1.0, 0.0
    sin_transmitted = n_incident / n_transmitted * math.sqrt(1.0 - cos_incident * cos_incident)
    if sin_transmitted >= 1.0:
        return 1.0, 0.0
    cos_transmitted = math.sqrt(1.0 - sin_transmitted * sin_transmitted)
    r_s = (n_incident * cos_incident - n_transmitted * cos_transmitted) / (
        n_incident * cos_incident + n_transmitted * cos_transmitted)
    r_p = (n_incident * cos_transmitted - n_transmitted * cos_incident) / (
        n_incident * cos_transmitted + n_transmitted * cos_incident)
    return 0.5 * (r_s * r_s + r_p * r_p), cos_transmitted


@njit(cache=True)
def _run_stream(state, photons, mu_a, mu_s, g, n_layer, z_top, z_bottom, n_above, n_below, edges,
                sums, sums_sq, t_sums, totals, launch_cos):
    """Trace ``photons`` photons; accumulate per-bin sums (and squares) of the top face's escapes,
    per-bin sums of the bottom face's (t_sums), and totals [R_d, R_d^2, T_d, absorbed] for one stream."""
    layers = mu_a.size
    bins = edges.size - 1
    for _ in range(photons):
        x = 0.0
        y = 0.0
        z = 0.0
        ux = math.sqrt(1.0 - launch_cos * launch_cos)
        uy = 0.0
        uz = launch_cos
        weight = 1.0
        layer = 0
        step_left = 0.0  # dimensionless (optical) step still to travel
        while True:
            if step_left == 0.0:
                step_left = -math.log(_splitmix64_uniform(state))
            mu_t = mu_a[layer] + mu_s[layer]
            # Distance to the layer's boundary along the direction of travel
            if uz > 0.0:
                to_boundary = (z_bottom[layer] - z) / uz
            elif uz < 0.0:
                to_boundary = (z_top[layer] - z) / uz
            else:
                to_boundary = np.inf
            step = step_left / mu_t if mu_t > 0.0 else np.inf
            if step >= to_boundary:
                # Hit the boundary: move onto it and keep the unused optical depth
                x += to_boundary * ux
                y += to_boundary * uy
                z = z_bottom[layer] if uz > 0.0 else z_top[layer]
                if mu_t > 0.0:
                    step_left = max(step_left - to_boundary * mu_t, 0.0)
                next_layer = layer + 1 if uz > 0.0 else layer - 1
                n_1 = n_layer[layer]
                if next_layer < 0:
                    n_2 = n_above
                elif next_layer >= layers:
                    n_2 = n_below
                else:
                    n_2 = n_layer[next_layer]
                reflectance, cos_transmitted = _fresnel(n_1, n_2, abs(uz))
                if _splitmix64_uniform(state) <= reflectance:
                    uz = -uz  # internal reflection (all or none, as MCML)
                elif next_layer < 0:
                    # Escaped through the top face: score it at its radius
                    radius = math.sqrt(x * x + y * y)
                    b = np.searchsorted(edges, radius, side="right") - 1
                    if 0 <= b < bins:
                        sums[b] += weight
                        sums_sq[b] += weight * weight
                    totals[0] += weight
                    totals[1] += weight * weight
                    break
                elif next_layer >= layers:
                    # Escaped through the bottom face (a slab): score it at its radius too
                    radius = math.sqrt(x * x + y * y)
                    b = np.searchsorted(edges, radius, side="right") - 1
                    if 0 <= b < bins:
                        t_sums[b] += weight
                    totals[2] += weight
                    break
                else:
                    if n_1 != n_2:  # refract by Snell's law
                        ux *= n_1 / n_2
                        uy *= n_1 / n_2
                        uz = cos_transmitted if uz > 0.0 else -cos_transmitted
                    layer = next_layer
                continue
            # Move, then deposit mu_a/mu_t of the weight (implicit capture)
            x += step * ux
            y += step * uy
            z += step * uz
            step_left = 0.0
            deposit = weight * mu_a[layer] / mu_t
            weight -= deposit
            totals[3] += deposit
            # Scatter: Henyey-Greenstein deflection (MCML's Spin) and uniform azimuth
            anisotropy = g[layer]
            xi = _splitmix64_uniform(state)
            if anisotropy == 0.0:
                cos_theta = 2.0 * xi - 1.0
            else:
                t = (1.0 - anisotropy * anisotropy) / (1.0 - anisotropy + 2.0 * anisotropy * xi)
                cos_theta = (1.0 + anisotropy * anisotropy - t * t) / (2.0 * anisotropy)
                cos_theta = min(1.0, max(-1.0, cos_theta))
            sin_theta = math.sqrt(1.0 - cos_theta * cos_theta)
            psi = 2.0 * math.pi * _splitmix64_uniform(state)
            cos_psi = math.cos(psi)
            sin_psi = math.sin(psi)
            if abs(uz) > 1.0 - 1e-12:
                ux = sin_theta * cos_psi
                uy = sin_theta * sin_psi
                uz = cos_theta if uz > 0.0 else -cos_theta
            else:
                root = math.sqrt(1.0 - uz * uz)
                new_ux = sin_theta * (ux * uz * cos_psi - uy * sin_psi) / root + ux * cos_theta
                new_uy = sin_theta * (uy * uz * cos_psi + ux * sin_psi) / root + uy * cos_theta
                uz = -sin_theta * cos_psi * root + uz * cos_theta
                ux = new_ux
                uy = new_uy
            # Russian roulette
            if weight < ROULETTE_THRESHOLD:
                if _splitmix64_uniform(state) <= ROULETTE_SURVIVAL:
                    weight /= ROULETTE_SURVIVAL
                else:
                    break


@njit(cache=True, parallel=True)
def _run_streams(seed, first_stream, photon_counts, mu_a, mu_s, g, n_layer, z_top, z_bottom, n_above, n_below,
                 edges, launch_cos):
    streams = photon_counts.size
    bins = edges.size - 1
    sums = np.zeros((streams, bins))
    sums_sq = np.zeros((streams, bins))
    t_sums = np.zeros((streams, bins))
    totals = np.zeros((streams, 4))
    for i in prange(streams):
        state = np.empty(1, dtype=np.uint64)
        # Each stream starts at a hashed point of the 2^64 cycle: hash(seed, stream index)
        state[0] = _mix64(_mix64(np.uint64(seed) + _GOLDEN) ^ _mix64(np.uint64(first_stream + i + 1)))
        _run_stream(state, photon_counts[i], mu_a, mu_s, g, n_layer, z_top, z_bottom, n_above, n_below, edges,
                    sums[i], sums_sq[i], t_sums[i], totals[i], launch_cos)
    return sums.sum(axis=0), sums_sq.sum(axis=0), t_sums.sum(axis=0), totals.sum(axis=0)


@dataclass(frozen=True)
class MonteCarloResult:
    """Radially binned diffuse reflectance of a pencil beam, per unit power entering (1/mm^2)."""

    bin_edges_mm: np.ndarray
    reflectance_per_mm2: np.ndarray  # mean over each annulus
    standard_error_per_mm2: np.ndarray
    total_reflectance: float  # all radii, R_d
    total_reflectance_standard_error: float
    total_transmittance: float
    absorbed: float
    photons: int
    seed: int
    specular_reflectance: float  # normal-incidence Fresnel at the top, not part of the above
    # the light that left through the bottom face (a slab), mean over each annulus (1/mm^2) around
    # the beam's axis: the transmitted profile
    transmittance_per_mm2: np.ndarray | None = None

    @property
    def bin_centers_mm(self) -> np.ndarray:
        return 0.5 * (self.bin_edges_mm[1:] + self.bin_edges_mm[:-1])


def _layer_arrays(layers: Sequence[Layer]):
    if not layers:
        raise DermisError("the Monte Carlo needs at least one layer")
    mu_a, mu_s, g, n, top, bottom = [], [], [], [], [], []
    depth = 0.0
    for i, layer in enumerate(layers):
        medium = layer.medium
        if medium.wavelength_count != 1:
            raise DermisError("the Monte Carlo runs one wavelength at a time; select() one first")
        if layer.semi_infinite and i != len(layers) - 1:
            raise DermisError("only the last layer may be semi-infinite")
        mu_a.append(float(medium.sigma_a_per_mm[0]))
        mu_s.append(float(medium.sigma_s_per_mm[0]))
        g.append(medium.g)
        n.append(medium.n)
        top.append(depth)
        depth += layer.thickness_mm
        bottom.append(depth)
    return tuple(np.array(v, dtype=np.float64) for v in (mu_a, mu_s, g, n, top, bottom))


def monte_carlo_reflectance(layers: Sequence[Layer], photons: int, bin_edges_mm, seed: int = 0,
                            n_above: float = 1.0, n_below: float = 1.0, progress=False,
                            incidence_cos: float = 1.0) -> MonteCarloResult:
    """Run MCML for a stack of ``layers`` (top first; scalar media; the last may be semi-infinite).

    ``bin_edges_mm``: increasing radial bin edges; ``progress``: False, True (a tqdm bar on
    stderr) or an open tqdm bar to advance. The first call compiles the kernel (cached on disk).
    ``incidence_cos``: the beam's cosine to the normal OUTSIDE (1: MCML's normal incidence); it is
    launched along the direction Snell's law refracts it to in the top layer (still per unit
    power entering: the entry's Fresnel loss is not part of the result).
    """
    photons = int(photons)
    if photons < 2:
        raise DermisError(f"the Monte Carlo needs at least 2 photons, got {photons}")
    edges = np.asarray(bin_edges_mm, dtype=np.float64)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0) or edges[0] < 0:
        raise DermisError("radial bin edges must be increasing and >= 0 mm")
    mu_a, mu_s, g, n, top, bottom = _layer_arrays(layers)
    if not 0.0 < float(incidence_cos) <= 1.0:
        raise DermisError(f"the incidence cosine must be in (0, 1], got {incidence_cos!r}")
    sin_inside = n_above / n[0] * math.sqrt(max(0.0, 1.0 - float(incidence_cos) ** 2))
    launch_cos = math.sqrt(max(0.0, 1.0 - sin_inside * sin_inside)) if sin_inside < 1.0 else 1e-6
    stream_count = -(-photons // STREAM_PHOTONS)
    counts = np.full(stream_count, STREAM_PHOTONS, dtype=np.int64)
    counts[-1] = photons - STREAM_PHOTONS * (stream_count - 1)

    bar, own_bar = progress, False
    if progress is True:
        from tqdm import tqdm

        bar, own_bar = tqdm(total=photons, unit="photon", unit_scale=True, desc="Monte Carlo", leave=False), True
    sums = np.zeros(edges.size - 1)
    sums_sq = np.zeros(edges.size - 1)
    t_sums = np.zeros(edges.size - 1)
    totals = np.zeros(4)
    try:
        for first in range(0, stream_count, CHUNK_STREAMS):
            chunk = counts[first:first + CHUNK_STREAMS]
            s, s2, ts, t = _run_streams(np.uint64(seed % 2**64), first, chunk, mu_a, mu_s, g, n, top, bottom,
                                        float(n_above), float(n_below), edges, launch_cos)
            sums += s
            sums_sq += s2
            t_sums += ts
            totals += t
            if bar:
                bar.update(int(chunk.sum()))
    finally:
        if own_bar:
            bar.close()

    area = np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    mean = sums / photons
    variance = np.maximum(sums_sq / photons - mean * mean, 0.0)
    total_mean = totals[0] / photons
    total_variance = max(totals[1] / photons - total_mean**2, 0.0)
    specular = ((n[0] - n_above) / (n[0] + n_above)) ** 2
    return MonteCarloResult(
        bin_edges_mm=edges,
        reflectance_per_mm2=mean / area,
        standard_error_per_mm2=np.sqrt(variance / (photons - 1)) / area,
        total_reflectance=float(total_mean),
        total_reflectance_standard_error=float(np.sqrt(total_variance / (photons - 1))),
        total_transmittance=float(totals[2] / photons),
        absorbed=float(totals[3] / photons),
        photons=photons,
        seed=int(seed),
        specular_reflectance=float(specular),
        transmittance_per_mm2=t_sums / photons / area,
    )


def annulus_average(profile, bin_edges_mm, order: int = 24) -> np.ndarray:
    """Mean of a radial profile over each annulus, integral 2 pi r R(r) dr / area (Gauss-Legendre).

    ``profile``: callable radius_mm (array) -> R (same shape, or with a trailing axis). Use it to
    compare an analytic profile with MonteCarloResult.reflectance_per_mm2 bin by bin.
    """
    edges = np.asarray(bin_edges_mm, dtype=np.float64)
    nodes, weights = np.polynomial.legendre.leggauss(order)
    lo, hi = edges[:-1, None], edges[1:, None]
    radius = 0.5 * (hi - lo) * nodes + 0.5 * (hi + lo)  # (B, order)
    values = np.asarray(profile(radius), dtype=np.float64)
    extra = (1,) * (values.ndim - 2)  # trailing axes (wavelengths) of the profile
    ring = (2.0 * np.pi * radius * 0.5 * (hi - lo) * weights).reshape(radius.shape + extra)
    area = (np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)).reshape((-1,) + extra)
    return (values * ring).sum(axis=1) / area
