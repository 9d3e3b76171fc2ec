"""Layered media: combining the profiles of slabs in the frequency domain (Donner & Jensen 2005,
"Light Diffusion in Multi-Layered Translucent Materials", section 4).

Light that crosses layer 1 (transmittance T1), is reflected by layer 2 (R2) and comes back
through layer 1 (T1) is a chain of 2-D convolutions; bouncing between the layers adds a geometric
series. In the frequency domain (hats: 2-D Fourier / Hankel transforms, hankel.py) convolutions
are products and the series sums in closed form:

    R12^ = R1^ + T1^ R2^ T1^ / (1 - R2^ R1^),        T12^ = T1^ T2^ / (1 - R2^ R1^).

dermis distinguishes the two faces of a slab whose boundaries differ (air above the epidermis,
dermis below it): R12^ = R1down^ + T1down^ R2^ T1up^ / (1 - R2^ R1up^), where "down" is light
entering through the top face and "up" light entering through the bottom face. A slab may also
pass part of the beam unscattered (``ballistic``), a delta at r = 0 whose transform is a constant.
A stack is combined from the bottom up, so any number of layers works.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from dermis.profiles.hankel import LogRadialGrid


@dataclass(frozen=True)
class LayerResponse:
    """Radial responses (1/mm^2, (N, L) on a LogRadialGrid) of one slab to a unit pencil beam.

    ``reflectance_down``: enters and leaves through the top face (for the top layer it may hold
    a singular single-scattering peak: it is never transformed); ``transmittance_down``: enters
    at the top, leaves at the bottom (diffuse part); ``reflectance_up`` / ``transmittance_up``:
    the same for light entering through the bottom face; ``ballistic``: (L,) power crossing
    unscattered. A semi-infinite bottom layer needs ``reflectance_down`` only.
    """

    reflectance_down: np.ndarray
    transmittance_down: np.ndarray | None = None
    reflectance_up: np.ndarray | None = None
    transmittance_up: np.ndarray | None = None
    ballistic: np.ndarray = field(default_factory=lambda: np.zeros(1))


@dataclass(frozen=True)
class LayeredReflectance:
    """R(r) of a stack on ``grid.radius_mm`` (N, L) and its total diffuse reflectance R_d (L,)."""

    grid: LogRadialGrid
    reflectance: np.ndarray
    total_reflectance: np.ndarray


def combine_layers(responses: Sequence[LayerResponse], grid: LogRadialGrid) -> LayeredReflectance:
    """Reflectance of a stack (top layer first) by Donner & Jensen 2005, bottom up."""
    if not responses:
        raise ValueError("a stack needs at least one layer")
    bottom = responses[-1]
    if len(responses) == 1:
        return LayeredReflectance(grid, np.asarray(bottom.reflectance_down), grid.total(bottom.reflectance_down))

    below_hat = grid.forward(bottom.reflectance_down)  # R^ of everything below the current layer
    below_total = grid.total(bottom.reflectance_down)
    for index in range(len(responses) - 2, -1, -1):
        layer = responses[index]
        ballistic = np.asarray(layer.ballistic, dtype=np.float64)
        # Transforms of the slab's responses (a delta transforms to a constant)
        down_hat = grid.forward(layer.transmittance_down) + ballistic
        up_hat = grid.forward(layer.transmittance_up) + ballistic
        back_hat = grid.forward(layer.reflectance_up)
        added_hat = down_hat * below_hat * up_hat / (1.0 - below_hat * back_hat)
        # The same at k = 0 from the profiles' integrals (exact totals, no transform error)
        down_total = grid.total(layer.transmittance_down) + ballistic
        up_total = grid.total(layer.transmittance_up) + ballistic
        back_total = grid.total(layer.reflectance_up)
        added_total = down_total * below_total * up_total / (1.0 - below_total * back_total)
        if index == 0:
            reflectance = np.asarray(layer.reflectance_down) + grid.inverse(added_hat)
            total = grid.total(layer.reflectance_down) + added_total
            return LayeredReflectance(grid, reflectance, total)
        below_hat = grid.forward(layer.reflectance_down) + added_hat
        below_total = grid.total(layer.reflectance_down) + added_total
    raise AssertionError("unreachable")
