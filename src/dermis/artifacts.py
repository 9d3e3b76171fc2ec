"""Artifact scan: isolated bright or saturated pixels (specks, thin lines) that a rendering shows
beyond what a reference of the same view shows.

Skin texture defeats a scan of one image alone (pores, freckles and hair are isolated bright or
saturated pixels too: a local median / MAD test flagged dozens of texture pixels at a z-score of 3
while missing nothing). A defect, though, is a pixel that is far brighter than BOTH its own
neighbourhood AND the reference at the same pixel, where the reference is a render of the same
scene and camera that shares the texture and the geometry but not the suspected mechanism (the same
technique with the term off, lambert, or an offline render). Per pixel p and channel c:

    excess_c(p)   = log2((I_c(p) + eps_c) / (R_c(p) + eps_c))                 stops above the reference
    speck(p)      = max_c [excess_c(p) - median_{w x w} excess_c]              stops above its neighbourhood's excess

The ratio removes the texture the two share (both multiply by the same albedo); subtracting the
neighbourhood's median excess removes what the term does smoothly (a back-lit ear that glows
as a whole), so what remains are features narrower than half the window: specks and lines.
eps_c is a fraction (EPS_FRACTION) of the reference's median over the mask, so dark shadow pixels
whose ratio is large but whose difference no one sees are not flagged. The median runs over mask
pixels only (silhouettes do not count as neighbours).

A pixel is flagged when speck(p) > threshold stops AND I(p) exceeds its own neighbourhood's median
(a pixel darker than its surroundings is no speck); flagged pixels are grouped into 8-connected
components, each reported with its size, peak and position. Units: stops (log2 of a radiance
ratio); images are linear radiance (H, W, 3), row 0 = top.

The speck scan cannot see defects that are BROAD (the neighbourhood's median takes them away) or
DARKER (it asks for a pixel brighter than its surroundings): a shadow-map leak lights a patch of
a shadow several pixels wide, a wrong term darkens or shifts the colour of a whole region. For
those, ``shifts`` compares the two images region by region without the neighbourhood step:

    shift(p)      = max_c excess_c(p)  (brighter)   or   -min_c excess_c(p)  (darker)

flagged where > threshold stops, grouped into 8-connected regions of at least ``min_pixels``
(one stray pixel of Monte Carlo noise is no region), optionally only where another mask says
(``where``). ``shadow_leaks`` is the brighter shift restricted to the reference's SHADOW (pixels
whose luminance is below ``shadow_fraction`` of the reference's median over the mask): light
where the reference has none. The reference must then be one whose shadows are right (the
offline reference's ray-cast shadows, dermis.reference), not the same technique with a term off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dermis.errors import DermisError

WINDOW_PX = 9  # the neighbourhood: a defect must be narrower than about half of it
THRESHOLD_STOPS = 0.5  # 41% brighter than both the reference and the neighbourhood's excess
EPS_FRACTION = 0.05  # eps_c = this x the reference's median of channel c over the mask


@dataclass(frozen=True)
class Speck:
    """One connected group of flagged pixels: size (pixels), peak speck value (stops), its pixel."""

    pixels: int
    peak_stops: float
    row: int
    col: int


def _masked_median(a: np.ndarray, mask: np.ndarray, w: int) -> np.ndarray:
    """Median of ``a`` over the w x w window of each pixel, counting mask pixels only (NaN where
    none); ``a`` (H, W)."""
    from numpy.lib.stride_tricks import sliding_window_view

    r = w // 2
    x = np.where(mask, a, np.nan).astype(np.float32)
    x = np.pad(x, r, constant_values=np.nan)
    win = sliding_window_view(x, (w, w)).reshape(a.shape[0], a.shape[1], w * w)
    out = np.full(a.shape, np.nan, np.float32)
    rows, cols = np.nonzero(mask)
    # only the mask's pixels: nanmedian over (n, w*w)
    out[rows, cols] = np.nanmedian(win[rows, cols], axis=1)
    return out


def speck_map(image, reference, mask, *, window: int = WINDOW_PX, eps_fraction: float = EPS_FRACTION) -> np.ndarray:
    """(H, W) float32: stops by which each mask pixel exceeds both the reference and its
    neighbourhood's excess (module docstring), 0 where it does not or outside the mask; a pixel no
    brighter than its own neighbourhood's median (max over channels) scores 0."""
    I = np.asarray(image, np.float64)[..., :3]
    R = np.asarray(reference, np.float64)[..., :3]
    m = np.asarray(mask, bool)
    if I.shape != R.shape or I.shape[:2] != m.shape:
        raise DermisError(f"speck_map: image {I.shape}, reference {R.shape} and mask {m.shape} must agree")
    if window < 3 or window % 2 == 0:
        raise DermisError(f"speck_map: window must be odd and >= 3, got {window}")
    if not m.any():
        return np.zeros(m.shape, np.float32)
    eps = eps_fraction * np.maximum(np.median(R[m], axis=0), 1e-12)
    score = np.zeros(m.shape, np.float32)
    brighter = np.zeros(m.shape, bool)
    for c in range(3):
        e = np.log2((I[..., c] + eps[c]) / (R[..., c] + eps[c]))
        s = e - _masked_median(e, m, window)
        score = np.maximum(score, np.where(m, s, 0.0).astype(np.float32))
        brighter |= I[..., c] > _masked_median(I[..., c], m, window)
    return np.where(m & brighter, np.maximum(score, 0.0), 0.0).astype(np.float32)


def scan(image, reference, mask, *, threshold_stops: float = THRESHOLD_STOPS, window: int = WINDOW_PX,
         eps_fraction: float = EPS_FRACTION) -> list[Speck]:
    """The defects of ``image`` beyond ``reference`` on ``mask``: 8-connected groups of pixels whose
    speck_map exceeds threshold_stops, largest peak first."""
    s = speck_map(image, reference, mask, window=window, eps_fraction=eps_fraction)
    return _regions(s, threshold_stops, 1)


def _regions(score: np.ndarray, threshold: float, min_pixels: int) -> list[Speck]:
    from scipy import ndimage

    lab, n = ndimage.label(score > threshold, structure=np.ones((3, 3), int))
    if n == 0:
        return []
    ids = np.arange(1, n + 1)
    sizes = ndimage.sum_labels(np.ones_like(score), lab, ids)
    peaks = ndimage.maximum(score, lab, ids)
    where = ndimage.maximum_position(score, lab, ids)
    out = [Speck(pixels=int(a), peak_stops=float(p), row=int(rc[0]), col=int(rc[1]))
           for a, p, rc in zip(sizes, peaks, where) if a >= min_pixels]
    return sorted(out, key=lambda sp: -sp.peak_stops)


def shift_map(image, reference, mask, *, darker: bool = False, eps_fraction: float = EPS_FRACTION) -> np.ndarray:
    """(H, W) float32: stops by which each mask pixel is brighter (or, with ``darker``, darker) than
    the reference in its most-changed channel, 0 outside the mask or where it is not."""
    I = np.asarray(image, np.float64)[..., :3]
    R = np.asarray(reference, np.float64)[..., :3]
    m = np.asarray(mask, bool)
    if I.shape != R.shape or I.shape[:2] != m.shape:
        raise DermisError(f"shift_map: image {I.shape}, reference {R.shape} and mask {m.shape} must agree")
    if not m.any():
        return np.zeros(m.shape, np.float32)
    eps = eps_fraction * np.maximum(np.median(R[m], axis=0), 1e-12)
    e = np.log2((I + eps) / (R + eps))
    s = -e.min(axis=2) if darker else e.max(axis=2)
    return np.where(m, np.maximum(s, 0.0), 0.0).astype(np.float32)


def shifts(image, reference, mask, *, darker: bool = False, threshold_stops: float = THRESHOLD_STOPS,
           min_pixels: int = 4, where=None, eps_fraction: float = EPS_FRACTION) -> list[Speck]:
    """Regions of at least ``min_pixels`` where ``image`` is brighter (``darker``: darker) than
    ``reference`` by more than threshold_stops (module docstring), inside ``mask`` (and ``where``
    if given), largest peak first."""
    if min_pixels < 1:
        raise DermisError(f"shifts: min_pixels must be >= 1, got {min_pixels}")
    m = np.asarray(mask, bool)
    if where is not None:
        w = np.asarray(where, bool)
        if w.shape != m.shape:
            raise DermisError(f"shifts: where {w.shape} and mask {m.shape} must agree")
        m = m & w
    return _regions(shift_map(image, reference, m, darker=darker, eps_fraction=eps_fraction), threshold_stops, min_pixels)


SHADOW_FRACTION = 0.25  # a reference pixel this far below the median luminance is in shadow


def shadow_leaks(image, reference, mask, *, shadow_fraction: float = SHADOW_FRACTION,
                 threshold_stops: float = THRESHOLD_STOPS, min_pixels: int = 4) -> list[Speck]:
    """Light where the reference has none: brighter regions (``shifts``) inside the reference's
    shadow, the pixels of ``mask`` whose luminance is below shadow_fraction of its median there."""
    R = np.asarray(reference, np.float64)[..., :3]
    m = np.asarray(mask, bool)
    if R.shape[:2] != m.shape:
        raise DermisError(f"shadow_leaks: reference {R.shape} and mask {m.shape} must agree")
    if not m.any():
        return []
    lum = R @ np.array([0.2126, 0.7152, 0.0722])
    shadow = lum < shadow_fraction * np.median(lum[m])
    return shifts(image, reference, m, where=shadow, threshold_stops=threshold_stops, min_pixels=min_pixels)
