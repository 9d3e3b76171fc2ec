"""The profile integral of the reference: diffuse light at x = integral over the surface of
R(|x - y|) E(y) dA(y), with R = sum_k w_k G(v_k, r) and |x - y| the true 3-D distance.

Quadrature: the midpoint rule over an exact partition of the surface into lattice cells
(sampling.surface_cells). Gaussian k is summed over cells of size h_k = m_k h_min, m_k the integer
nearest sigma_k / (2 h_min) (at least 1): about 230 cells within its cutoff on a flat surface,
whatever its width. Coarse cells are unions of the finest ones and carry their area-weighted
mean irradiance (a cell average), so coarse sets neither alias texture or shadow detail nor blur
beyond the Gaussian itself. Gaussians narrower than the finest cells resolve
(sigma_k < RESOLVED_RATIO h_min) are widened to sigma = RESOLVED_RATIO h_min; callers choose h_min
below the pixel footprint so that this costs less than the sampling noise (tests/test_reference.py).

Cutoff: Gaussian k is cut where it falls below CUTOFF_RELATIVE (1e-4) of its peak,
r_k = sigma_k sqrt(2 ln 1e4) = 4.29 sigma_k; for the widest skin Gaussian (v = 7.41 mm^2) that is
11.7 mm: the far side of an ear or a nostril wing lies inside it, so light through thin parts
comes from the same integral (no separate translucency term). Neighbours within r_k come from
a KD-tree (scipy.spatial.cKDTree, dual-tree sparse distance matrix), in chunks of query points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

CUTOFF_RELATIVE = 1e-4
"""A Gaussian is truncated where it falls below this fraction of its peak."""
SPACING_PER_SIGMA = 0.5
"""Cell size of Gaussian k's sample set, in units of sigma_k (rounded to a multiple of h_min)."""
RESOLVED_RATIO = 1.5
"""The narrowest sigma the finest cells (size h_min) integrate: 1.5 h_min. On an unbroken lattice
0.7 h would do (the lattice sum of a Gaussian deviates by 2 exp(-2 pi^2 (sigma / h)^2)), but the
cells clipped at triangle edges are irregular: under uniform light a plane's radiance deviates by
up to 2.7% at 0.7 h, 1.1% at 1 h, 0.3% at 1.5 h, 0.15% at 2 h (measured, 5 mm triangles)."""
PAIRS_PER_CHUNK = 6_000_000
from dermis.techniques.shared import TISSUE_TAU  # noqa: E402  (ssss's blurs use the same test)

"""paths="tissue": a pair is skipped where the segment between the points leaves either of them
into the air more than 14.5 degrees above its tangent plane (sin = 0.25). A heuristic: across a
1 mm crease it removes 96% of the straight-path light (shallower segments still count), and on a
concave sheet of curvature radius R it keeps neighbours closer than R / 2."""


def cutoff_radius(variance_mm2) -> float:
    """r where G(v, r) / G(v, 0) = CUTOFF_RELATIVE: sigma sqrt(2 ln(1 / CUTOFF_RELATIVE))."""
    return float(np.sqrt(2.0 * variance_mm2 * np.log(1.0 / CUTOFF_RELATIVE)))


@dataclass
class Level:
    """One Gaussian of the profile as the reference integrates it."""

    index: int
    variance_mm2: float  # as in the profile
    effective_variance_mm2: float  # after widening to what its sample set resolves
    cutoff_mm: float
    set_index: int


@dataclass
class SampleSetPlan:
    factor: int  # cell size in units of the finest cells
    spacing_mm: float
    cutoff_mm: float  # the largest cutoff of the Gaussians using it
    levels: list


def plan_levels(profile, min_spacing_mm: float):
    """Give each Gaussian of ``profile`` a cell size, an integer multiple m of ``min_spacing_mm``
    near SPACING_PER_SIGMA sigma_k; Gaussians with the same m share a set. Returns (levels, sets)."""
    h_min = float(min_spacing_mm)
    variances = np.asarray(profile.variances_mm2, np.float64)
    sets: dict[int, SampleSetPlan] = {}
    levels: list[Level] = []
    for k in np.argsort(variances):
        v = float(variances[k])
        m = max(1, int(round(SPACING_PER_SIGMA * math.sqrt(v) / h_min)))
        if m not in sets:
            sets[m] = SampleSetPlan(m, m * h_min, 0.0, [])
        v_eff = max(v, (RESOLVED_RATIO * h_min) ** 2) if m == 1 else v
        levels.append(Level(int(k), v, v_eff, cutoff_radius(v_eff), -1))
        sets[m].levels.append(levels[-1])
        sets[m].cutoff_mm = max(sets[m].cutoff_mm, levels[-1].cutoff_mm)
    ordered = [sets[m] for m in sorted(sets)]
    for i, s in enumerate(ordered):
        for lvl in s.levels:
            lvl.set_index = i
    levels.sort(key=lambda l: l.index)
    return levels, ordered


@numba.njit(cache=True)
def _tissue_path(ex, ey, ez, c, npx, npy, npz, nqx, nqy, nqz, tau):
    """The path through the tissue from p to q: (s^2 - c^2 in mm^2, how much longer than the
    chord it is; the share of the light that takes it), (0, 1) where the chord runs in the tissue,
    (0, 0) where no path joins them (another surface).

    (ex, ey, ez) = q - p (mm), c its length, n_p / n_q the unit normals (out of the skin) of the
    surfaces at p and q. h_q = (q - p).n_p is q's height above p's tangent plane, h_p = -(q - p).n_q
    p's above q's. Both <= tau c: the chord leaves neither end into the air (flat or convex skin),
    s = c. Both >= -tau c with one above: a CONCAVE bend; its chord crosses the air over the valley
    and the light goes round the bend inside the tissue. For the sharpest surface the normals
    allow, the two tangent planes meeting on their common line (direction a = n_p x n_q / sin phi),
    the shortest path is straight on the unfolded wedge: p and q lie h_p / sin phi and h_q / sin phi
    from the fold, t = (q - p).a apart along it, s^2 = (h_p + h_q)^2 / sin^2 phi + t^2 (a rounded
    bend is shorter: c (phi/2) / sin(phi/2) for a circular arc against the wedge's c / cos(phi/2),
    1.02 c and 1.06 c at phi = 40 degrees). Facing sheets (phi -> 180 degrees): s -> infinity.
    Otherwise (one end below the other's plane, e.g. parallel normals 2 mm apart: a step; or the
    wedge's chord across the fold more than tau from the real one) no single bend joins them. The
    share: 1 for bends up to 60 degrees, falling linearly in cos phi to 0 at 90 (clamp(2 n_p.n_q,
    0, 1)): a sharper concave bend on a mesh is a fold whose sides are different tissue (closed
    lips: 96-120 degrees across their line in the front-key view at 768 px), joined out of sight
    if at all. That cut is a modelling choice, not a measured one. ssss's blurs use the same rule
    (ssss/kernel.glsl, ssss_tissue_path)."""
    hq = ex * npx + ey * npy + ez * npz
    hp = -(ex * nqx + ey * nqy + ez * nqz)
    tol = tau * c
    if hq <= tol and hp <= tol:
        return 0.0, 1.0
    if hq < -tol or hp < -tol:
        return 0.0, 0.0
    ax = npy * nqz - npz * nqy
    ay = npz * nqx - npx * nqz
    az = npx * nqy - npy * nqx
    sin_phi = math.sqrt(ax * ax + ay * ay + az * az)
    if sin_phi < 1e-3:
        return 0.0, 0.0  # facing sheets: s > 250 c, nothing passes
    t = (ex * ax + ey * ay + ez * az) / sin_phi
    a = max(hp, 0.0) / sin_phi  # p's distance from the fold line, mm
    b = max(hq, 0.0) / sin_phi  # q's
    cos_phi = npx * nqx + npy * nqy + npz * nqz
    # the chord across the fold the wedge predicts (law of cosines, apex angle pi - phi) against the
    # real one, both in the plane across the fold: more than tau apart, no wedge joins them
    across = math.sqrt(max(c * c - t * t, 0.0))
    wedge = math.sqrt(a * a + b * b + 2.0 * a * b * cos_phi)
    if abs(wedge - across) > tau * across:
        return 0.0, 0.0
    return max((a + b) * (a + b) + t * t - c * c, 0.0), min(max(2.0 * cos_phi, 0.0), 1.0)


@numba.njit(cache=True)
def _accumulate(qi, sj, dist, weights, values, variances, cutoffs, qpos, spos, qn, sn, tau, out):
    """out[q, k, :] += w_j G(v_k, d) E_j for every pair (q, j) at distance d < cutoff_k; with
    tau < 1, d is the path inside the tissue (_tissue_path: round a concave bend where the
    segment leaves either end into the air, n . (other - self) > tau d) and pairs it does not join
    are skipped (qn, sn: unit normals of the query points and samples)."""
    K = variances.shape[0]
    norm = np.empty(K)
    inv2v = np.empty(K)
    for k in range(K):
        norm[k] = 1.0 / (2.0 * np.pi * variances[k])
        inv2v[k] = 1.0 / (2.0 * variances[k])
    check = tau < 1.0
    for p in range(qi.shape[0]):
        q = qi[p]
        j = sj[p]
        d = dist[p]
        d2 = d * d
        share = 1.0
        if check and d > 0.0:
            # the path inside the tissue (qn, sn point out of the skin): the chord or round a bend
            extra, share = _tissue_path(spos[j, 0] - qpos[q, 0], spos[j, 1] - qpos[q, 1], spos[j, 2] - qpos[q, 2], d,
                                        qn[q, 0], qn[q, 1], qn[q, 2], sn[j, 0], sn[j, 1], sn[j, 2], tau)
            if share <= 0.0:
                continue
            d2 += extra
            d = math.sqrt(d2)
        for k in range(K):
            if d < cutoffs[k]:
                g = share * weights[j] * norm[k] * np.exp(-d2 * inv2v[k])
                out[q, k, 0] += g * values[j, 0]
                out[q, k, 1] += g * values[j, 1]
                out[q, k, 2] += g * values[j, 2]


def gather(query_mm, sample_mm, sample_weights, sample_values, variances, cutoffs, progress=None,
           query_normals=None, sample_normals=None, tissue_tau=None):
    """For each query point q and Gaussian k: sum_j w_j G(v_k, |q - y_j|) E_j over |q - y_j| < r_k.

    ``query_mm`` (n, 3), ``sample_mm`` (m, 3), ``sample_weights`` (m,) mm^2, ``sample_values``
    (m, 3), ``variances``/``cutoffs`` (K,). Returns ((n, K, 3) float64, the number of pairs visited).
    ``progress``: a callable taking the number of query points done. ``tissue_tau``: with unit
    normals of both point sets, pairs whose straight segment leaves either end into the air at more
    than asin(tau) above its tangent plane exchange light along the path round the concave bend
    between them, or none where no bend joins them (_tissue_path; None: every pair counts,
    straight).
    """
    variances = np.asarray(variances, np.float64)
    cutoffs = np.asarray(cutoffs, np.float64)
    n = len(query_mm)
    out = np.zeros((n, len(variances), 3))
    if n == 0 or len(sample_mm) == 0:
        return out, 0
    r = float(cutoffs.max())
    stree = cKDTree(sample_mm)
    # expected neighbours per query: density (samples per mm^2 of surface) times the disc area
    density = len(sample_mm) / max(float(np.sum(sample_weights)), 1e-300)
    per_query = max(density * math.pi * r * r * 2.0, 1.0)  # x2: thin parts see both sides
    chunk = int(max(256, min(n, PAIRS_PER_CHUNK / per_query)))
    pairs = 0
    w = np.ascontiguousarray(sample_weights, np.float64)
    vals = np.ascontiguousarray(sample_values, np.float64)
    qpos = np.ascontiguousarray(query_mm, np.float64)
    spos = np.ascontiguousarray(sample_mm, np.float64)
    if tissue_tau is None:
        tau = 2.0
        qn = np.zeros((1, 3))
        sn = np.zeros((1, 3))
    else:
        tau = float(tissue_tau)
        qn = np.ascontiguousarray(query_normals, np.float64)
        sn = np.ascontiguousarray(sample_normals, np.float64)
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        qtree = cKDTree(query_mm[s:e])
        m = qtree.sparse_distance_matrix(stree, r, output_type="ndarray")
        pairs += len(m)
        _accumulate(np.ascontiguousarray(m["i"], np.int64), np.ascontiguousarray(m["j"], np.int64),
                    np.ascontiguousarray(m["v"], np.float64), w, vals, variances, cutoffs, qpos[s:e], spos,
                    qn[s:e] if tissue_tau is not None else qn, sn, tau, out[s:e])
        if progress is not None:
            progress(e - s)
    return out, pairs
