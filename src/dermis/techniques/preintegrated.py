"""Pre-integrated skin (``preintegrated``): Penner & Borshukov 2011, "Pre-Integrated Skin Shading"
(GPU Pro 2, ch. II.1; SIGGRAPH 2011 course "Pre-Integrated Skin Rendering"); NVIDIA FaceWorks.

What it approximates: the diffusion profile's convolution of the light, WITHOUT any blur pass,
from three local quantities looked up in tables computed at start-up from the active profile
(the same Gaussians as every other technique, weights normalised per channel):

* curvature: the surface near a point is taken as a ring of radius r = 1 / curvature; light
  scattered from around the ring wraps past the terminator and reddens it (Penner eq. 1):
      D(theta, r) = int_{-pi}^{pi} max(cos(theta + x), 0) K(2 r sin(x / 2)) dx
                    / int_{-pi}^{pi} K(2 r sin(x / 2)) dx              per channel, theta = acos(N.L)
  Penner takes K = R, the 2-D radial profile. dermis takes K = the profile integrated across the
  ring, sum_k w_k g(v_k, d) with 1-D Gaussians (``RING_PROFILE = "line"``; "radial" is Penner's):
  that is exactly the profile integrated over a CYLINDER's surface, it stays within 10% of a
  sphere's, and it keeps each Gaussian's weight w_k, where R on a 1-D ring weights Gaussian k by
  w_k / sqrt(2 pi v_k) and wraps 3-7x less light than the sphere (see :func:`ring_kernel`).
  At zero curvature D is max(N.L, 0); for every curvature its integral over the light angle is
  that of max(N.L, 0) (the ring only moves light around). Curvature is precomputed per vertex
  from the mesh (the mean magnitude of the normal curvatures along its edges, 1/mm through
  mm_per_unit) and falls back to Penner's length(fwidth(N)) / length(fwidth(P)) when
  ``curvature_source`` is "derivatives".
* shadows: a soft (PCF) shadow value s in [0, 1] is a position across the penumbra, of width w
  (mm on the surface: 1 / |grad s| from screen derivatives, bounded by the PCF filter's diameter
  projected on the surface). Penner's second table scatters the light's edge with the profile:
  the edge, sharpened by the width the scattering adds (at most to PENUMBRA_SHARPEN_MIN w),
  convolved with the profile across it (its 1-D marginal: the same Gaussians in 1-D) and rescaled
  to [0, 1] over the penumbra, per channel: red reaches further into the shadow than green and blue.
  Rescaled to [0, 1], the table moves light only within the penumbra it is given; a channel whose
  scattering widens an edge by more than the PCF's penumbra (d'Eon's red, 2.35 mm, against ~1.2 mm
  on the head at the shadow tile 2048) also reads a wide penumbra: the shadow box-filtered over the
  PCF's width plus the wide part's scattering width (:func:`wide_widths_mm`) on the tangent plane,
  through a second table of the same rows whose edge is a step (the box's ramp is its own width;
  :func:`penumbra_tables`), blended in by (wide part's width - PCF) / PCF. There each channel's wide Gaussians (2 sigma > WIDE_SPLIT_MM) are read
  from the box and its narrow ones from the PCF through Penner's table of the narrow part (one box for
  the whole profile put red's narrow half as deep in the shadow as its tail at a lit wedge's tip
  between cast shadows: olive tips; benchmarks/RESULTS.md, round 20, olive20). Without the wide
  penumbra a cast shadow narrower than red's reach, the upper lid's on the closed eye's slit, was
  black where Cycles is dark red (benchmarks/RESULTS.md, round 19, eyes19).
* surface detail: each channel's normal is the normal map filtered by that channel's profile,
  sum_k w_k (the map at the mip level whose box has Gaussian k's standard deviation, never finer
  than the pixel's own footprint): Penner's "blurred normals", red the blurriest. One level at the
  channel's rms radius (rounds 1-6) took red's from its wide tail and lost the third of red's
  weight within 0.25 mm: red/green grain along a terminator (tests/test_preintegrated.py).

* folds (``fold_scattering``, off by default for its cost, issue 12): the tables above see only the point's own ring and its
  own shadow value, so no light crosses a concave fold (an eyelid crease, a nostril: the wall facing
  away has D = 0, the facing wall lies in the fold's shadow, s = 0). skin.frag gathers the light
  the shadow map's lit points scatter to the point at their true 3-D distance (the reference's
  surface integral: cos(theta_Q) dA_Q is the map's own area across the light; translucent shadow
  maps, Dachsbacher & Stamminger 2003), Gaussian by Gaussian with a 7-point rule on a plane
  through the point, for the Gaussians the map resolves, counting only lit points on or above the
  point's tangent plane (below is the ring's wrap and the thin parts' transmittance), and takes
  per channel the larger of that and Penner's D S: a lit plane and a convex surface keep D S
  exactly (tests/test_preintegrated_folds.py).

* interreflection: the bounce light between skin surfaces, E_b and its higher orders per vertex (the Renderer's shared
  pass, dermis.gl.interreflection.SharedBounce, once per lighting change), added as the ambient is,
  through none of the tables: the ring wraps a light's N.L past its terminator and the penumbra
  table scatters a shadow map's edge; E_b is an irradiance already integrated over the hemisphere
  (no terminator), gathered per vertex and interpolated linearly (no shadow-map edge, no normal-map
  detail). What the profile would still do to it is smooth it below the vertices' spacing (2.6 mm
  on the head): measured on the head (side view, exact sampled convolution with tissue paths), the
  red channel moves by 8% of E_b (sum |change| / sum E_b; mostly the bake's per-vertex Monte Carlo
  noise averaged out), green and blue by 0.1%; not applied (benchmarks/RESULTS.md, "Round 8,
  branch bounce8").

Everything else is shared with the other techniques: lights, shadows, environment, specular
(common/skin_specular.glsl), energy conservation (N.L in, N.V out) and the translucency of thin
parts from the shadow map's thickness (common/transmittance.glsl, Jimenez et al. 2010), and tsd's
baked subsurface transfer of thin, curled parts where the mesh has one (common/subsurface_transfer.glsl
at the texture-space uv, gathered from the shared rho E once per lighting change, added to the light
leaving the skin: the back-lit ear's same-side light round its curls).
Known failure modes: light crosses folds only from what the light's shadow map sees (points
hidden from the light, e.g. behind a nostril's rim, send nothing; lights without shadows gather
nothing), along straight lines (across the air of a fold: the reference's "straight" paths, an
upper bound of the tissue path), only through the Gaussians wider than two shadow texels (a
crease's green and blue, narrower, stay dark: its light is red), the
ring model assumes one curvature at a scale of the profile's width (mesh curvature finer than
that is meaningless, a coarse mesh blurs it), the penumbra width from derivatives is noisy on
2x2 pixel quads (bounded by the projected filter size), and the table sharpens narrow penumbras.
The wide penumbra reads a shadow narrower than its box as one edge (a 2.5 mm strip's centre gets
0.89 of the closed form's red), cuts the scattered tail beyond half its box (red 0.044 off), and lies on the
tangent plane: the receiver's own concave rise is lifted out only up to a 0.5 rad turn of its normal.
Shaders: shaders/preintegrated/skin.frag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from dermis.gl.resources import prepared, set_uniform
from dermis.gl.subsurface_transfer import SubsurfaceTransfer
from dermis.gl.thickness import ThicknessTexture
from dermis.techniques.base import Frame, Technique, TranslucentOptions, check_bool, check_choice, draw_mesh, draw_surfaces
from dermis.techniques.shared import (INTERREFLECTION_DEFINE, MAX_GAUSSIANS, LightCountPrograms, OutputMode, Unit,
                                      bind_interreflection, bind_sampler, casts_translucency, directional_albedo_uniforms, prepare_interreflection,
                                      set_profile_uniforms, subsurface_transfer_uniforms, surface_detail_uniforms,
                                      translucency_uniforms)

# The diffuse table: N.L along s (odd, so N.L = 0 is a texel centre and max(N.L, 0) interpolates
# exactly), curvature along t on a square-root axis (fine steps where faces mostly are).
DIFFUSE_TABLE_SIZE = (257, 64)  # (N.L, curvature)
CURVATURE_MAX_PER_MM = 1.0  # r = 1 mm: thinner than an ear's rim; higher curvatures clamp
# The penumbra table: shadow value along s, penumbra width along t (log axis).
PENUMBRA_TABLE_SIZE = (129, 64)  # (shadow value, width)
PENUMBRA_WIDTH_RANGE_MM = (0.05, 100.0)
PENUMBRA_SHARPEN_MIN = 0.5  # the sharpened edge keeps at least this fraction of the PCF penumbra
# The wide penumbra splits each channel's profile: the Gaussians whose own edge widening 2 sigma_k is
# at most this (mm) are read from the PCF's shadow (Penner's premise holds for them: the PCF's ~1-1.2 mm
# penumbra on the head at the shadow tile 2048 is as wide), the rest from the box (d'Eon's skin: sigma
# 0.08, 0.22, 0.43 mm narrow; 0.75, 1.41, 2.72 mm wide; red's narrow share 0.451, green's 0.989, blue's 0.993).
WIDE_SPLIT_MM = 1.0
RING_PROFILE = "line"  # the ring's kernel: "line" (profile integrated across the ring) or "radial" (Penner)

UNIT_DIFFUSE_TABLE, UNIT_PENUMBRA_TABLE, UNIT_THICKNESS = Unit.FIRST_FREE, Unit.FIRST_FREE + 1, Unit.FIRST_FREE + 2
FOLD_DEFINE = "PREINTEGRATED_FOLDS"  # skin.frag: the fold gather compiled in (fold_scattering)
GAUSSIANS_DEFINE = "PREINTEGRATED_GAUSSIANS"  # skin.frag: the profile's Gaussian count, a compile-time constant
UNIT_SHADOW_DEPTH = Unit.FIRST_FREE + 3  # the shadow atlas again, its depths read without comparison (fold_scattering)
UNIT_NORMAL_LOD = Unit.FIRST_FREE + 4  # the normal map again, through an isotropic sampler (the blurred normals' textureLod)
UNIT_TRANSFER = Unit.FIRST_FREE + 5  # the baked subsurface transfer's grid (common/subsurface_transfer.glsl)
UNIT_FAR_FACE = Unit.FIRST_FREE + 6  # the far face's points behind each texel (gl/thickness.py, common/transmittance.glsl)

_TABLE_CACHE: dict = {}


# ---------------------------------------------------------------------- tables (numpy)
def ndotl_axis(n: int = DIFFUSE_TABLE_SIZE[0]) -> np.ndarray:
    """N.L at the table's columns: -1 .. 1 at texel centres."""
    return np.linspace(-1.0, 1.0, n)


def curvature_axis(n: int = DIFFUSE_TABLE_SIZE[1]) -> np.ndarray:
    """Curvature (1/mm) at the table's rows: CURVATURE_MAX * (j / (n - 1))^2."""
    return CURVATURE_MAX_PER_MM * np.linspace(0.0, 1.0, n) ** 2


def shadow_axis(n: int = PENUMBRA_TABLE_SIZE[0]) -> np.ndarray:
    return np.linspace(0.0, 1.0, n)


def penumbra_width_axis(n: int = PENUMBRA_TABLE_SIZE[1]) -> np.ndarray:
    """Penumbra widths (mm) at the table's rows, log-spaced over PENUMBRA_WIDTH_RANGE_MM."""
    lo, hi = PENUMBRA_WIDTH_RANGE_MM
    return lo * (hi / lo) ** np.linspace(0.0, 1.0, n)


def _profile_key(profile, *extra):
    v = np.asarray(profile.variances_mm2, np.float64).tobytes()
    return (v, np.asarray(profile.weights, np.float64).tobytes(), extra)


def ring_kernel(profile, distance_mm, ring_profile: str = "line") -> np.ndarray:
    """The weight, per channel, of ring points at chord distance d (mm): (len(d), 3).

    "radial": Penner's literal R(d), the 2-D radial profile. "line" (dermis's default): the
    profile integrated across the ring, sum_k w_k exp(-d^2 / 2 v_k) / sqrt(2 pi v_k) (a 2-D
    Gaussian's line integral is the 1-D Gaussian of the same variance). A ring stands for a
    curved surface, and integrating R over a CYLINDER's surface (ring angle x, axis y) gives
    exactly the ring integral with this kernel, since chord^2 = (2 r sin(x/2))^2 + y^2. With the
    radial kernel each Gaussian counts w_k / sqrt(2 pi v_k) instead of w_k: the narrow ones dominate
    and the wrap past the terminator is 3-7x weaker than on a sphere of the same radius (d'Eon's
    red at 1/r = 0.1-0.3 /mm, N.L = 0); the line kernel is within 10% of the sphere there."""
    prof = profile.normalized()
    d = np.asarray(distance_mm, np.float64)
    v = prof.variances_mm2
    if ring_profile == "radial":
        return prof.evaluate(d)
    if ring_profile != "line":
        raise ValueError(f"ring_profile must be 'line' or 'radial', got {ring_profile!r}")
    g = np.exp(-(d[:, None] ** 2) / (2.0 * v[None, :])) / np.sqrt(2.0 * np.pi * v[None, :])
    return g @ prof.weights


def ring_diffuse(profile, ndotl, curvature_per_mm, ring_profile: str = "line", samples: int = 8193) -> np.ndarray:
    """Penner's D(N.L, 1/r) for one curvature, per channel: (len(ndotl), 3).

    D(theta) = int max(cos(theta + x), 0) K(2 r sin(x/2)) dx / int K(2 r sin(x/2)) dx over the
    ring angle x, K from :func:`ring_kernel`. The lit arc is |theta + x| < pi/2, where
    cos(theta + x) = cos(theta) cos(x) - sin(theta) sin(x): D is read off the running integrals of
    K cos x and K sin x (trapezoid rule, |x| <= min(pi, 10 sigma_max / r): beyond, the chord
    exceeds 6 sigma_max), interpolated at the arc's ends: O(samples) per curvature.
    """
    ndotl = np.clip(np.asarray(ndotl, np.float64), -1.0, 1.0)
    if curvature_per_mm <= 0.0:
        return np.repeat(np.maximum(ndotl, 0.0)[:, None], 3, axis=1)
    r = 1.0 / curvature_per_mm
    x_max = min(math.pi, 10.0 * math.sqrt(float(np.max(profile.variances_mm2))) / r)
    x = np.linspace(-x_max, x_max, samples)
    k = ring_kernel(profile, 2.0 * r * np.abs(np.sin(x / 2.0)), ring_profile)  # (samples, 3)
    h = x[1] - x[0]

    def running(f):  # running trapezoid integral of f (samples, 3) from -x_max, at each x
        return np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * h * (f[1:] + f[:-1]), axis=0)])

    total = running(k)[-1]
    run_cos, run_sin = running(k * np.cos(x)[:, None]), running(k * np.sin(x)[:, None])
    theta = np.arccos(ndotl)
    a = -0.5 * math.pi - theta  # lit arc [a, b] in x, a in [-3pi/2, -pi/2]
    b = 0.5 * math.pi - theta
    full_ring = x_max >= math.pi
    arcs = [(np.clip(a, -x_max, x_max), np.clip(b, -x_max, x_max))]
    if full_ring:  # the part of the arc below -pi is the part above pi - (a + 2 pi) on the ring
        arcs.append((np.where(a < -math.pi, a + 2.0 * math.pi, math.pi), np.full_like(a, math.pi)))
    out = np.zeros((len(ndotl), 3))
    for c in range(3):
        for lo, hi in arcs:
            ic = np.interp(hi, x, run_cos[:, c]) - np.interp(lo, x, run_cos[:, c])
            is_ = np.interp(hi, x, run_sin[:, c]) - np.interp(lo, x, run_sin[:, c])
            out[:, c] += (np.cos(theta) * ic - np.sin(theta) * is_) / total[c]
    return np.maximum(out, 0.0)


def diffuse_table(profile, size=DIFFUSE_TABLE_SIZE, ring_profile: str = RING_PROFILE) -> np.ndarray:
    """(rows = curvature, cols = N.L, 3) float32 table of D; row 0 is max(N.L, 0)."""
    key = _profile_key(profile, "diffuse", tuple(size), ring_profile)
    if key not in _TABLE_CACHE:
        nl = ndotl_axis(size[0])
        rows = [ring_diffuse(profile, nl, k, ring_profile) for k in curvature_axis(size[1])]
        _TABLE_CACHE[key] = np.stack(rows).astype(np.float32)
    return _TABLE_CACHE[key]


def _ramp_convolved(x, width, variance):
    """A linear ramp from 0 at x = -width/2 to 1 at +width/2, convolved with a 1-D Gaussian of the
    given variance (closed form: (F(x + a/2) - F(x - a/2)) / a, F(y) = y Phi(y/s) + s phi(y/s))."""
    from scipy.special import ndtr

    s = math.sqrt(variance)

    def F(y):
        return y * ndtr(y / s) + s * np.exp(-0.5 * (y / s) ** 2) / math.sqrt(2.0 * math.pi)

    if width <= 1e-9:
        return ndtr(x / s)
    return (F(x + width / 2) - F(x - width / 2)) / width


def channel_scattering_widths_mm(profile) -> np.ndarray:
    """How much each channel's profile widens a sharp shadow edge: twice its rms radius along one
    axis, 2 sqrt(sum_k w_kc v_k), (3,) mm (d'Eon's skin: red 2.35, green 0.52, blue 0.31)."""
    prof = profile.normalized()
    return 2.0 * np.sqrt(prof.weights.T @ prof.variances_mm2)


def profile_part(profile, wide: bool):
    """The Gaussians of the profile wider (``wide``) or not than WIDE_SPLIT_MM (2 sigma_k), each
    channel's weights normalised to 1 over that part (a channel with none there keeps zeros), and
    that part's share of each channel's weight, (3,): (SumOfGaussians, share)."""
    from dermis.profiles.gaussians import SumOfGaussians

    prof = profile.normalized()
    keep = (2.0 * np.sqrt(prof.variances_mm2) > WIDE_SPLIT_MM) == wide
    if not keep.any():
        return None, np.zeros(3)
    w = prof.weights[keep]
    share = w.sum(axis=0)
    return SumOfGaussians(prof.variances_mm2[keep], w / np.where(share > 0.0, share, 1.0), prof.name), share


def wide_widths_mm(profile) -> np.ndarray:
    """How much each channel's WIDE part (:func:`profile_part`, its own weights normalised) widens a sharp
    edge, 2 x its rms radius along one axis, (3,) mm; 0 for a channel with no wide Gaussian (d'Eon's skin:
    red 3.14, green 2.08, blue 1.51). The wide penumbra's box holds only this part (round 20, olive20), so its
    width and its blend come from it, not from the whole profile's (red 2.35: the box then cut red's tail
    beyond half its width harder; benchmarks/RESULTS.md, round 21, wide21)."""
    part, _ = profile_part(profile, True)
    return np.zeros(3) if part is None else channel_scattering_widths_mm(part)


def scattering_width_mm(profile) -> float:
    """How much the profile widens a sharp shadow edge: that of its widest channel (2.35 mm for d'Eon's red)."""
    return float(np.max(channel_scattering_widths_mm(profile)))


def sharp_edge_width_mm(profile, width_mm):
    """The light's own edge under a PCF penumbra of width w: what is left once the scattering's
    widening is taken out (Penner's "sharpening"), w - scattering width, but at least
    PENUMBRA_SHARPEN_MIN w: wide penumbras keep their width, narrow ones are sharpened. Not for
    the wide penumbra's box, whose ramp holds no scattering (:func:`scattered_shadow`, box)."""
    w = np.asarray(width_mm, np.float64)
    return np.maximum(w - scattering_width_mm(profile), PENUMBRA_SHARPEN_MIN * w)


def scattered_shadow(profile, shadow, width_mm, box: bool = False) -> np.ndarray:
    """Penner's penumbra scattering for one penumbra width, per channel: (len(shadow), 3).

    The soft shadow s sits at x = (s - 1/2) w across a penumbra of width w (mm). The light's own
    edge there is a linear ramp of width :func:`sharp_edge_width_mm`, or, with ``box``, a step
    (width 0): the wide penumbra's s is a box filter of width w over the shadow map's own compares
    (common/shadow.glsl, shadow_box_curved), and a box of width w over a step is exactly a linear
    ramp of width w, so s gives the position across the step itself and no width is left to take
    out (each tap's bilinear 2x2 compare adds about a texel, left out). Sharpened by the scattering
    only, that edge kept the PCF's ~1.2 mm ramp, which the box's taps do not have: red at the lit
    side of a cast shadow fell to 0.66 of the lit skin's where a step gives 0.75 (front-key's nose
    shadow on the cheek), a pale green fringe (benchmarks/RESULTS.md, round 19, fringe19). The light
    under it, scattered across the edge, is that ramp convolved with the profile's 1-D marginal
    sum_k w_k g(v_k, x) (the line integral of a 2-D Gaussian is the 1-D Gaussian of the same
    variance), rescaled to 0 at s = 0 and 1 at s = 1: the table cannot light what the shadow map
    calls fully shadowed, nor darken what it calls fully lit. Odd about s = 1/2, so the light
    summed across the penumbra is that of the PCF ramp: the table moves light, red furthest."""
    prof = profile.normalized()
    s = np.asarray(shadow, np.float64)
    edge = 0.0 if box else float(sharp_edge_width_mm(profile, width_mm))
    xs = np.concatenate([(s - 0.5) * width_mm, [-0.5 * width_mm, 0.5 * width_mm]])
    out = np.zeros((len(xs), 3))
    for v, w in zip(prof.variances_mm2, prof.weights):
        out += _ramp_convolved(xs, edge, v)[:, None] * w[None, :]
    lo, hi = out[-2], out[-1]
    return np.clip((out[:-2] - lo) / np.maximum(hi - lo, 1e-12), 0.0, 1.0)


def penumbra_table(profile, size=PENUMBRA_TABLE_SIZE, box: bool = False) -> np.ndarray:
    """(rows = penumbra width, cols = shadow value, 3) float32 table of the scattered shadow
    (``box``: the wide penumbra's, a step under the box; :func:`scattered_shadow`)."""
    key = _profile_key(profile, "penumbra", tuple(size), PENUMBRA_SHARPEN_MIN, box)
    if key not in _TABLE_CACHE:
        s = shadow_axis(size[0])
        rows = [scattered_shadow(profile, s, w, box) for w in penumbra_width_axis(size[1])]
        _TABLE_CACHE[key] = np.stack(rows).astype(np.float32)
    return _TABLE_CACHE[key]


def penumbra_tables(profile, size=PENUMBRA_TABLE_SIZE) -> np.ndarray:
    """The texture skin.frag reads, three blocks of the same rows (widths): penumbra_table's; the wide
    penumbra's, of the profile's wide part (:func:`profile_part`; the edge a step: skin.frag's wide
    penumbra is a box filter of the shadow map's compares, whose ramp is the box's own width, not a
    penumbra); Penner's of the narrow part (read at the PCF's s). (3 x rows, cols, 3)."""
    blocks = [penumbra_table(profile, size)]
    for wide in (True, False):
        part, _ = profile_part(profile, wide)
        blocks.append(penumbra_table(part, size, box=wide) if part is not None else
                      np.broadcast_to(shadow_axis(size[0])[None, :, None], (size[1], size[0], 3)).astype(np.float32))
    return np.concatenate(blocks, 0)


# ---------------------------------------------------------------------- curvature (numpy)
def vertex_curvature(positions, normals, indices, mm_per_unit: float = 1.0) -> np.ndarray:
    """Curvature per vertex in 1/mm: the mean over the vertex's edges (i, j) of the magnitude of
    the normal curvature along the edge, |(n_j - n_i).(p_j - p_i)| / |p_j - p_i|^2 (exact on a
    sphere: 1/R; 0 on planes and across split normals). Unsigned, like Penner's
    length(fwidth(N)) / length(fwidth(P)): the ring wraps light on concave surfaces as on convex
    ones, and a signed mean curvature would read flat along every convex-concave transition."""
    p = np.asarray(positions, np.float64)
    n = np.asarray(normals, np.float64)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    d = p[e[:, 1]] - p[e[:, 0]]
    dn = n[e[:, 1]] - n[e[:, 0]]
    len2 = np.einsum("ij,ij->i", d, d)
    ok = len2 > 0
    k = np.zeros(len(e))
    k[ok] = np.abs(np.einsum("ij,ij->i", dn[ok], d[ok])) / len2[ok]
    sums = np.bincount(e[ok].ravel(), weights=np.repeat(k[ok], 2), minlength=len(p))
    counts = np.bincount(e[ok].ravel(), minlength=len(p))
    return (sums / np.maximum(counts, 1) / float(mm_per_unit)).astype(np.float32)


def _table_texture(ctx, table: np.ndarray):
    """An RGBA32F texture (RGB32F samples up to 10x slower on llvmpipe) of a (rows, cols, 3) table:
    linear, clamp-to-edge, no mipmaps; numpy row 0 is uploaded first (t = 0)."""
    data = np.ascontiguousarray(np.concatenate([table, np.ones(table.shape[:2] + (1,))], axis=2), np.float32)
    t = ctx.texture((data.shape[1], data.shape[0]), 4, data.tobytes(), dtype="f4", alignment=4)
    t.filter = (moderngl.LINEAR, moderngl.LINEAR)
    t.repeat_x = t.repeat_y = False
    return t


# ---------------------------------------------------------------------- the technique
@dataclass(frozen=True)
class PreintegratedOptions(TranslucentOptions):
    curvature_source: str = "mesh"  # "mesh": per-vertex curvature; "derivatives": Penner's fwidth
    blurred_normals: bool = True  # per-channel normal-map mip levels
    penumbra_scattering: bool = True  # the penumbra table (else plain PCF)
    # light scattered across concave folds, gathered from the shadow map (skin.frag). Off by default:
    # on an NVIDIA H100 it made the preintegrated pass 5.5x dearer (6.7 -> 37.1 ms at 1024^2; llvmpipe
    # 1.8x) for a crease that reaches ~40% of the surface-integral reference instead of ~15%, where the
    # shared bounce light (interreflection) already lifts it (benchmarks/RESULTS.md, "Round 8 merged")
    fold_scattering: bool = False

    def validate(self, technique: str) -> None:
        super().validate(technique)
        check_choice(f"{technique}: curvature_source", self.curvature_source, ("mesh", "derivatives"))
        check_bool(f"{technique}: blurred_normals", self.blurred_normals)
        check_bool(f"{technique}: penumbra_scattering", self.penumbra_scattering)
        check_bool(f"{technique}: fold_scattering", self.fold_scattering)


class PreintegratedSkin(Technique):
    name = "preintegrated"
    description = "pre-integrated skin (Penner 2011): curvature and penumbra tables of the profile, no blur passes"
    Options = PreintegratedOptions

    def __init__(self, renderer, **options):
        super().__init__(renderer, **options)
        # one program per light count, its light loop unrolled (LightCountPrograms); with the shared
        # one bounce (the Renderer's, made with the first technique that reads it) another; with
        # fold_scattering the fold gather compiled in (PREINTEGRATED_FOLDS: without it, its code behind
        # the uniform that turns it off still cost ~9% of the pass on llvmpipe); and per profile's
        # Gaussian count (PREINTEGRATED_GAUSSIANS: the blurred normals' loop at a constant trip count,
        # -7% on llvmpipe). The scene's sets are compiled now, others when first drawn.
        self._defines = {"MAX_GAUSSIANS": MAX_GAUSSIANS, "DERMIS_VERTEX_CURVATURE": None}
        self._program_sets = {}  # (bounce, fold, Gaussian count) -> LightCountPrograms
        scene = renderer.scene
        k = scene.profile.k if scene is not None else MAX_GAUSSIANS
        self.programs = self._programs_for(False, self.options.fold_scattering, k).compile_for(scene)
        self._programs_for(True, self.options.fold_scattering, k).compile_for(scene)
        self.prog = None  # when set (benchmarks and tests swap shaders in), drawn instead of the above
        self.profile_tables = {}  # "diffuse", "penumbra": textures of the active profile
        self._profile_key = None
        self.curvature = None  # per-vertex curvature (1/mm) of the active mesh, numpy
        self._curvature_buffer = None
        self._vaos = {}  # id(program) -> (vertex array with the curvature, program): per mesh
        renderer.interreflection  # the shared one bounce: made with the first technique that reads it
        self.thickness = ThicknessTexture(self.ctx, filtered=True)  # thickness behind each texel (common/transmittance.glsl)
        self.transfer = SubsurfaceTransfer(self.ctx)  # the baked subsurface transfer of thin, curled parts
        self._mesh_key = None
        # the shadow atlas's depths as plain values (skin.frag's fold gather): a sampler object, whose
        # state overrides the texture's comparison mode on its own unit only (OpenGL 4.5, 8.2)
        self.depth_sampler = self.ctx.sampler(filter=(moderngl.NEAREST, moderngl.NEAREST), compare_func="",
                                              repeat_x=False, repeat_y=False)
        # the normal map as the blurred normals read it (skin.frag's textureLod at a chosen level):
        # a sampler object without anisotropy. A lookup at an explicit level has zero derivatives, so
        # the GL spec's anisotropic footprint is 1:1 there and a GPU returns the trilinear value
        # either way; Mesa's llvmpipe instead runs its elliptical filter (3-6x the cost) and blurs past
        # the level (benchmarks/RESULTS.md, "Passes on llvmpipe, round 5"; round 9, branch screen9)
        self.normal_lod_sampler = self.ctx.sampler(anisotropy=1.0)

    # ------------------------------------------------------------------ resources
    def _ensure_profile_tables(self, frame: Frame):
        profile = frame.scene.profile
        key = frame.keys["profile_tables"]
        if key == self._profile_key:
            return
        with frame.timer("preintegrated_tables"):
            for t in self.profile_tables.values():
                t.release()
            self.profile_tables = {"diffuse": _table_texture(self.ctx, diffuse_table(profile)),
                                   "penumbra": _table_texture(self.ctx, penumbra_tables(profile))}
        self._profile_key = key
        frame.passes_run.append("preintegrated_tables")

    def _ensure_curvature(self, frame: Frame):
        scene = frame.scene
        key = frame.keys["mesh_curvature"]  # a new GpuScene calls scene_changed(): the VAO is rebuilt
        if key == self._mesh_key:
            return
        self._release_mesh()
        with frame.timer("preintegrated_curvature"):
            m = scene.mesh
            self.curvature = vertex_curvature(m.positions, m.normals, m.indices, scene.mm_per_unit)
            self._curvature_buffer = self.ctx.buffer(np.ascontiguousarray(self.curvature, np.float32).tobytes())
        self._mesh_key = key
        frame.passes_run.append("preintegrated_curvature")

    def _vao(self, frame: Frame, prog):
        """``prog``'s vertex array: the scene's vertex buffer and the per-vertex curvature, made per
        program (a vertex array draws with the program it was made for) and mesh."""
        key = id(prog)  # the program is held in the entry: its id cannot be reused while cached
        if key not in self._vaos:
            content = [frame.gpu.vertex_content(prog)]
            if "in_curvature" in prog:
                content.append((self._curvature_buffer, "1f", "in_curvature"))
            self._vaos[key] = (self.ctx.vertex_array(prog, content, frame.gpu.ibo), prog)
        return self._vaos[key][0]

    def _release_mesh(self):
        for vao, _ in self._vaos.values():
            vao.release()
        self._vaos = {}
        if self._curvature_buffer is not None:
            self._curvature_buffer.release()
        self._curvature_buffer = None
        self._mesh_key = None

    def scene_changed(self):
        self._release_mesh()

    # ------------------------------------------------------------------ frame

    def _programs_for(self, bounce: bool, fold: bool, gaussians: int) -> LightCountPrograms:
        key = (bool(bounce), bool(fold), int(gaussians))
        if key not in self._program_sets:
            defines = dict(self._defines, **{GAUSSIANS_DEFINE: int(gaussians)})
            if bounce:
                defines[INTERREFLECTION_DEFINE] = 1
            if fold:
                defines[FOLD_DEFINE] = 1
            # per light signature too (the kinds and shadow kernels as constants: the same floats; round 24, sig24)
            self._program_sets[key] = LightCountPrograms(self.ctx, "common/mesh.vert", "preintegrated/skin.frag", defines,
                                                         signature=True)
        return self._program_sets[key]

    def light_programs(self, scene, bounce: bool) -> LightCountPrograms:
        """The per-count programs (LightCountPrograms) the light loop is drawn from for ``scene``
        (its profile's Gaussian count), with or without the shared bounce, with the fold gather where
        ``fold_scattering`` is on."""
        return self._programs_for(bounce, self.options.fold_scattering, scene.profile.k)

    def override_light_program(self, prog) -> None:
        """Draw ``prog`` instead of the per-count programs (None: back to them); benchmarks, tests."""
        self.prog = prog

    def render(self, frame: Frame, output_mode: int = OutputMode.FULL) -> None:
        self._ensure_profile_tables(frame)
        self._ensure_curvature(frame)
        profile = frame.scene.profile
        # the shared one bounce (rebuilt only on a lighting change): a diffuse term like the ambient,
        # through none of the tables (E_b is an irradiance from the whole hemisphere, gathered per
        # vertex: no terminator for the ring to wrap, no shadow-map edge for the penumbra table, no
        # normal-map detail for the blurred normals; common/interreflection.glsl)
        bounce = prepare_interreflection(frame)
        prog = self.prog if self.prog is not None else self.light_programs(frame.scene, bounce)(frame.lights.count, frame.lights.lights)
        vao = self._vao(frame, prog)
        # the baked transfer of thin, curled parts (gathered only on a lighting change; before the target is bound)
        subsurface_transfer_uniforms(prog, frame, self.transfer, self.options.translucency, UNIT_TRANSFER)
        with frame.timer("preintegrated"):
            frame.target.use()
            self.ctx.enable(moderngl.DEPTH_TEST)
            self.ctx.disable(moderngl.CULL_FACE)
            if bounce:
                bind_interreflection(frame, prog)
            bind_sampler(prog, "uDiffuseTable", self.profile_tables["diffuse"], UNIT_DIFFUSE_TABLE)
            bind_sampler(prog, "uPenumbraTable", self.profile_tables["penumbra"], UNIT_PENUMBRA_TABLE)
            bind_sampler(prog, "uThicknessMap", self.thickness.get(frame, max(self.renderer.irradiance_size // 2, 1)),
                         UNIT_THICKNESS)
            bind_sampler(prog, "uFarFaceMap", self.thickness.far_face, UNIT_FAR_FACE)
            set_profile_uniforms(prog, profile, MAX_GAUSSIANS)
            translucency_uniforms(prog, self.options.translucency and casts_translucency(frame.scene), self.options.translucency_strength,
                                  frame.scene)
            set_uniform(prog, "uCurvatureMaxPerMm", float(CURVATURE_MAX_PER_MM))
            set_uniform(prog, "uPenumbraWidthRangeMm", tuple(float(x) for x in PENUMBRA_WIDTH_RANGE_MM))
            # per profile (its key), not per frame: a camera-only frame computes no scene uniform
            prepared(prog, "profile_widths", frame.keys["profile_tables"],
                     lambda p: (set_uniform(p, "uWideWidthMm", tuple(float(x) for x in wide_widths_mm(profile))),
                                set_uniform(p, "uNarrowShare", tuple(float(x) for x in profile_part(profile, False)[1]))))
            set_uniform(prog, "uCurvatureFromMesh", 1.0 if self.options.curvature_source == "mesh" else 0.0)
            set_uniform(prog, "uBlurredNormals", 1.0 if self.options.blurred_normals else 0.0)
            set_uniform(prog, "uPenumbraScattering", 1.0 if self.options.penumbra_scattering else 0.0)
            fold = self.options.fold_scattering and frame.shadows.depth is not None
            set_uniform(prog, "uFoldScattering", 1.0 if fold else 0.0)
            # the sampler always on its own unit: a sampler2D and the atlas's sampler2DShadow on one
            # unit is an error at draw time even where the branch that reads it is not taken
            set_uniform(prog, "uShadowDepth", int(UNIT_SHADOW_DEPTH))
            if fold:
                bind_sampler(prog, "uShadowDepth", frame.shadows.depth, UNIT_SHADOW_DEPTH)
                self.depth_sampler.use(UNIT_SHADOW_DEPTH)
            directional_albedo_uniforms(prog, frame.scene)
            surface_detail_uniforms(prog, frame.scene.material, output_mode)
            uses_lod_sampler = self._bind_normal_lod(frame, prog)
            draw_mesh(frame, prog, vao=vao)
            if fold:
                self.depth_sampler.clear(UNIT_SHADOW_DEPTH)  # the unit's own state again for whoever binds it next
            if uses_lod_sampler:
                self.normal_lod_sampler.clear(UNIT_NORMAL_LOD)
        frame.passes_run.append("preintegrated")
        draw_surfaces(frame, output_mode)  # the non-skin surfaces, with depth testing

    def _bind_normal_lod(self, frame: Frame, prog) -> bool:
        """The scene's normal map on UNIT_NORMAL_LOD with :attr:`normal_lod_sampler`: the map's own
        filter and wrap, anisotropy 1. Returns whether the program reads it."""
        tex = frame.gpu.textures["normal"]
        if prog.get("uNormalMapLod", None) is None:
            return False
        smp = self.normal_lod_sampler
        smp.filter = tex.filter
        smp.repeat_x, smp.repeat_y = tex.repeat_x, tex.repeat_y
        bind_sampler(prog, "uNormalMapLod", tex, UNIT_NORMAL_LOD)
        smp.use(UNIT_NORMAL_LOD)
        return True

    def debug_buffers(self) -> dict:
        if self.renderer.last_frame is None or self._curvature_buffer is None:
            return {}
        out = {"curvature_per_mm": self.renderer.side_render(self.name, OutputMode.CURVATURE),
               "specular": self.renderer.side_render(self.name, OutputMode.SPECULAR)}
        for key in ("diffuse", "penumbra"):
            t = self.profile_tables.get(key)
            if t is not None:
                w, h = t.size
                out[f"table_{key}"] = np.frombuffer(t.read(), np.float32).reshape(h, w, 4)[::-1, :, :3].copy()
        return out

    def release(self):
        self._release_mesh()
        self.thickness.release()
        self.transfer.release()
        self.depth_sampler.release()
        self.normal_lod_sampler.release()
        for t in self.profile_tables.values():
            t.release()
        for p in self._program_sets.values():
            p.release()
        self._program_sets = {}

