"""Skin specular: the Kelemen / Szirmay-Kalos BRDF with a Beckmann distribution (numpy, no GL).

What it is: the specular term of d'Eon & Luebke 2007, "Advanced Techniques for Realistic Real-Time
Skin Rendering", GPU Gems 3 chapter 14, section 14.3 (specular surface reflectance), which uses the
physically plausible but cheap BRDF of Kelemen & Szirmay-Kalos 2001, "A Microfacet Based Coupled
Specular-Matte BRDF Model with Importance Sampling" (Eurographics short paper):

    f_spec(L, V) = rho_s * P(h) * F(V.h) / dot(h_u, h_u),   h_u = L + V (UNnormalised), h = h_u / |h_u|
    specular     = N.L * f_spec(L, V)                       (times light radiance and shadow)

Inputs and units: unit vectors N, L, V in any one space; ``m`` the Beckmann roughness (RMS
microfacet slope, dimensionless; skin about 0.3; Weyrich et al. 2006 measured it per face
region); ``rho_s`` a dimensionless scale (skin about 0.18); ``f0`` the normal-incidence Fresnel
reflectance (0.028 for refractive index 1.4). Everything is per unit light radiance.

Normalisation (read this before comparing with other renderers): P(h) follows d'Eon's code and has
NO 1/pi, so integral P(h) (N.h) dw_h = pi, not 1 (a normalised Beckmann NDF D = P / pi). The
functions here keep d'Eon's formulas as written; dermis renders physical radiance, so the shaders
divide f_spec and the albedo a(cos, m) by pi (the radiometric convention is stated once, in
dermis/techniques/shared.py). The table :func:`rho_dt_table` integrates f_spec exactly as written
above (rho_s = 1), as d'Eon's rho_dt shader does; see :func:`rho_dt` for energy conservation.

Tables for the GPU (uploaded by :func:`dermis.gl.tables.upload_specular_tables`; the shader side is
``shaders/common/brdf.glsl``). Both share the roughness axis y:

    m(y) = M_MIN * (M_MAX / M_MIN) ** y,  y in [0, 1] at TEXEL CENTRES (row j: y = j / (rows - 1)),
    M_MIN = 0.05, M_MAX = 1.0  (log-spaced: the Beckmann peak 1/m^2 changes fastest at small m).
    Outside [M_MIN, M_MAX] the shader clamps m.

* Beckmann table, float32 (rows = size_m, cols = size_ndoth), stores P itself (no 0.5 P^0.1 encoding):
  column i: x = i / (cols - 1) = sqrt(1 - N.h) in [0, 1] at texel centres, i.e. N.h = 1 - x^2.
  Near the peak tan^2(alpha) ~ 2 x^2, so P is close to a Gaussian in x of standard deviation m / 2
  and linear filtering stays accurate (test_specular measures it); a table linear in N.h would put
  the whole m = 0.1 lobe inside two 256-texel columns.
* rho_dt table, float32 (rows = size_m, cols = size_cos), stores the specular albedo a(cos, m)
  (rho_s = 1, see :func:`rho_dt`): column i: x = i / (cols - 1) = sqrt(cos_theta) in [0, 1] at
  texel centres, i.e. cos_theta = x^2. a climbs steeply towards grazing (from 2.1 to 2.7 between
  cos = 0.016 and 0 at m = 0.05); the square root puts 8 columns there instead of 1.

Texel-centre addressing in GLSL for a table of width W: s = (x * (W - 1) + 0.5) / W.
Known limits: no shadowing-masking term (Kelemen's 1 / dot(h, h) approximates it), so the albedo
rises at grazing angles: a(cos, m) exceeds 1 below cos ~ 0.25 and reaches 2.75 (m = 0.05,
cos = 0; a / pi stays below 0.88), so the energy left for diffuse, 1 - rho_s * a / pi, stays >= 0
for rho_s <= pi / 2.75 = 1.14 (skin's 0.18 .. 0.34 fits). P is for an isotropic surface; the tables cover m in [0.05, 1].
"""

from __future__ import annotations

import sys
from functools import lru_cache

import numpy as np

SKIN_F0 = 0.028
"""Schlick F0 of skin's oil layer, ((n - 1) / (n + 1))^2 for n = 1.4 is 0.0278 (d'Eon uses 0.028)."""

M_MIN = 0.05
"""Smallest Beckmann roughness the tables hold (the shader clamps m to [M_MIN, M_MAX])."""
M_MAX = 1.0
"""Largest Beckmann roughness the tables hold."""

BECKMANN_TABLE_SIZE = (512, 256)
"""Default Beckmann table size (N.h columns, m rows): float32, 512 KiB."""
RHO_DT_TABLE_SIZE = (64, 64)
"""Default rho_dt table size (cos columns, m rows)."""

TABLE_ATLAS = {"beckmann": (0, 0, BECKMANN_TABLE_SIZE[0], BECKMANN_TABLE_SIZE[1]),
               "rho_dt": (0, BECKMANN_TABLE_SIZE[1], RHO_DT_TABLE_SIZE[0], RHO_DT_TABLE_SIZE[1])}
"""Where the GPU keeps the two default tables: texel rectangles (x0, y0, cols, rows) of ONE R32F
texture (dermis.gl.tables), the Beckmann table in rows 0..255 and the rho_dt table below it, so
the two take one sampler unit. Each table's texel centres keep their values and positions
relative to its rectangle: a lookup clamped to the rectangle's centres reads what the table's
own texture read (brdf.glsl specular_table_coord)."""
TABLE_ATLAS_SIZE = tuple(1 << (max(r[i] + r[i + 2] for r in TABLE_ATLAS.values()) - 1).bit_length() for i in (0, 1))
"""(cols, rows) of the atlas, (512, 512): powers of two, so a table's normalised coordinate differs
from its own texture's by a power-of-two factor, which float arithmetic keeps exact (the Beckmann
table's lookups are bit-identical; the rho_dt table's row offset of 256 rounds its t coordinate to
2^-15 texel)."""


def _dot(a, b):
    return np.sum(np.asarray(a, dtype=np.float64) * np.asarray(b, dtype=np.float64), axis=-1)


def roughness_axis(size_m: int) -> np.ndarray:
    """The m of each table row: m_j = M_MIN * (M_MAX / M_MIN) ** (j / (size_m - 1))."""
    y = np.arange(size_m, dtype=np.float64) / (size_m - 1)
    return M_MIN * (M_MAX / M_MIN) ** y


def roughness_to_y(m) -> np.ndarray:
    """Inverse of :func:`roughness_axis` as a coordinate in [0, 1] (before texel-centre scaling)."""
    m = np.clip(np.asarray(m, dtype=np.float64), M_MIN, M_MAX)
    return np.log(m / M_MIN) / np.log(M_MAX / M_MIN)


def beckmann_ndf(ndoth, m):
    """Beckmann 1963 via d'Eon & Luebke 2007 (GPU Gems 3, 14.3, PHBeckmann):
    P(h) = exp(-tan^2(alpha) / m^2) / (m^2 cos^4(alpha)), alpha = angle(N, h); NO 1/pi.

    integral P (N.h) dw_h over the hemisphere is pi. N.h <= 0 gives 0.
    """
    c = np.asarray(ndoth, dtype=np.float64)
    m = np.asarray(m, dtype=np.float64)
    positive = c > 0.0
    c_safe = np.where(positive, c, 1.0)
    cos2 = c_safe * c_safe
    tan2 = (1.0 - c_safe) * (1.0 + c_safe) / cos2  # (1 - c^2) / c^2, written to keep digits near c = 1
    p = np.exp(-tan2 / (m * m)) / (m * m * cos2 * cos2)
    return np.where(positive, p, 0.0)


def fresnel_schlick(vdoth, f0=SKIN_F0):
    """Schlick 1994, "An Inexpensive BRDF Model for Physically-based Rendering":
    F = F0 + (1 - F0) (1 - V.h)^5, with V.h clamped to [0, 1]."""
    c = np.clip(np.asarray(vdoth, dtype=np.float64), 0.0, 1.0)
    return f0 + (1.0 - f0) * (1.0 - c) ** 5


def ksk_specular(n, l, v, m, rho_s, f0=SKIN_F0):
    """Kelemen & Szirmay-Kalos 2001 as in d'Eon & Luebke 2007 (GPU Gems 3, 14.3, KS_Skin_Specular):
    N.L * rho_s * P(h) * F(V.h) / dot(h_u, h_u), h_u = L + V, h = normalize(h_u).

    ``n, l, v``: unit vectors, arrays (..., 3) that broadcast; ``m``, ``rho_s``: broadcast to (...).
    Returns (...) float64, zero where N.L <= 0 or N.V <= 0.
    """
    n = np.asarray(n, dtype=np.float64)
    l = np.asarray(l, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    ndotl = _dot(n, l)
    ndotv = _dot(n, v)
    h_u = l + v
    h_len2 = _dot(h_u, h_u)
    lit = (ndotl > 0.0) & (ndotv > 0.0) & (h_len2 > 0.0)
    h_len2_safe = np.where(lit, h_len2, 1.0)
    h = h_u / np.sqrt(h_len2_safe)[..., None]
    p = beckmann_ndf(_dot(n, h), m)
    f = fresnel_schlick(_dot(v, h), f0)
    spec = ndotl * np.asarray(rho_s, dtype=np.float64) * p * f / h_len2_safe
    return np.where(lit, spec, 0.0)


def blinn_phong_specular(n, l, v, shininess, ks):
    """Blinn 1977 with the energy normalisation (n + 8) / (8 pi) (Akenine-Moller, Haines &
    Hoffman 2008, Real-Time Rendering, 3rd ed., section 7.6): ks (n + 8) / (8 pi) (N.h)^n N.L, zero where N.L <= 0
    or N.V <= 0. Arrays (..., 3) broadcast as in :func:`ksk_specular`. The baseline technique's term.
    """
    n_ = np.asarray(n, dtype=np.float64)
    l = np.asarray(l, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    ndotl = _dot(n_, l)
    ndotv = _dot(n_, v)
    h_u = l + v
    h_len = np.sqrt(np.maximum(_dot(h_u, h_u), 1e-300))
    ndoth = np.maximum(_dot(n_, h_u) / h_len, 0.0)
    shininess = np.asarray(shininess, dtype=np.float64)
    spec = np.asarray(ks, dtype=np.float64) * (shininess + 8.0) / (8.0 * np.pi) * ndoth**shininess * ndotl
    return np.where((ndotl > 0.0) & (ndotv > 0.0), spec, 0.0)


@lru_cache(maxsize=4)
def _beckmann_table_cached(size_ndoth: int, size_m: int) -> np.ndarray:
    x = np.arange(size_ndoth, dtype=np.float64) / (size_ndoth - 1)
    ndoth = 1.0 - x * x  # x = sqrt(1 - N.h) at texel centres
    m = roughness_axis(size_m)
    table = beckmann_ndf(ndoth[None, :], m[:, None]).astype(np.float32)
    table.setflags(write=False)
    return table


def beckmann_table(size_ndoth: int = BECKMANN_TABLE_SIZE[0], size_m: int = BECKMANN_TABLE_SIZE[1]):
    """Beckmann P(N.h, m) of :func:`beckmann_ndf` tabulated for linear filtering (d'Eon & Luebke
    2007, section 14.3, precompute it into a texture; float32 here, so P is stored as is).

    Returns (table, description): ``table`` float32 (size_m, size_ndoth), read-only and cached;
    row j holds m_j = M_MIN (M_MAX / M_MIN)^(j / (size_m - 1)), column i holds N.h = 1 - x_i^2 with
    x_i = i / (size_ndoth - 1), both AT TEXEL CENTRES. ``description`` is a dict of that mapping.
    """
    if size_ndoth < 2 or size_m < 2:
        raise ValueError("beckmann_table needs at least 2 x 2 texels")
    return _beckmann_table_cached(int(size_ndoth), int(size_m)), {
        "quantity": "Beckmann P(h) (no 1/pi), float32",
        "x": "sqrt(1 - N.h) in [0, 1], column i at i / (cols - 1) (texel centres)",
        "y": f"log(m / {M_MIN}) / log({M_MAX} / {M_MIN}) in [0, 1], row j at j / (rows - 1)",
        "m_range": (M_MIN, M_MAX),
        "shape": (int(size_m), int(size_ndoth)),
    }


def rho_dt(cos_theta, m, rho_s=1.0, f0=SKIN_F0, n_xi: int = 96, n_phi: int = 64):
    """Directional-hemispherical specular reflectance, d'Eon & Luebke 2007 (GPU Gems 3, section 14.3
    and its rho_dt precomputation listing): rho_dt(V) = integral over the hemisphere of
    f_spec(L, V) (N.L) dw_L, with f_spec as in :func:`ksk_specular` (N.L is already in it).

    CONVENTION: this returns the integral itself, rho_s * a(cos, m), where a is the albedo for
    rho_s = 1 (the quantity :func:`rho_dt_table` stores). The fraction of light left for the diffuse
    term is 1 - rho_s * a(N.L, m) / pi on the way in and 1 - rho_s * a(N.V, m) / pi on the way out.
    KSK is reciprocal, so one table serves L and V.

    Because P has no 1/pi (module docstring), a is pi times the albedo of the physically normalised
    lobe: the specular that dermis renders (divided by pi, as physical radiance) reflects
    rho_s * a / pi of the incident energy, so that is what shaders/common/energy.glsl removes from the
    diffuse. d'Eon's factor 1 - rho_s * a (docs/skin-rendering.md section 1) would remove pi times too much.

    Quadrature, in the half-vector domain (dw_L = 4 (V.h) dw_h, dot(h_u, h_u) = 4 (V.h)^2):
        a = integral P(h) F(V.h) (N.L) / (V.h) dw_h  over V.h > 0 and N.L > 0,
    with the Beckmann lobe importance-sampled on a deterministic midpoint grid (n_xi x 2 n_phi
    nodes; phi over [0, pi] by symmetry about the plane of N and V). The N.L > 0 cut at grazing
    angles limits the accuracy (tests/test_specular.py measures it against brute force).
    ``cos_theta`` = N.V in [0, 1] and ``m`` > 0 broadcast together; returns float64 of their shape.
    A per-point reference (about 1 ms a point); renderers use :func:`rho_dt_table` on the GPU.
    """
    cos_theta, m = np.broadcast_arrays(np.asarray(cos_theta, dtype=np.float64), np.asarray(m, dtype=np.float64))
    albedo = np.empty(cos_theta.shape, dtype=np.float64)
    flat = albedo.reshape(-1)
    for k, (mu, mk) in enumerate(zip(cos_theta.reshape(-1), m.reshape(-1))):
        flat[k] = _albedo(np.array([mu]), float(mk), f0, n_xi, n_phi)[0]
    return np.asarray(rho_s, dtype=np.float64) * albedo


def _albedo(cos_theta, m: float, f0: float, n_xi: int, n_phi: int) -> np.ndarray:
    """a(cos, m) for a 1-D array of view cosines and one roughness, vectorised over (cos, xi, phi)."""
    # Beckmann importance sampling (Walter et al. 2007, eq. 28): tan^2(theta_h) = m^2 t, t = -ln(1 - xi);
    # then P(h) (N.h) dw_h = (1/2) e^-t dt dphi = (1/2) dxi dphi.
    xi = (np.arange(n_xi, dtype=np.float64) + 0.5) / n_xi
    phi = (np.arange(n_phi, dtype=np.float64) + 0.5) / n_phi * np.pi
    cos_h = (1.0 / np.sqrt(1.0 - m * m * np.log1p(-xi)))[None, :, None]
    sin_h = np.sqrt(np.maximum(1.0 - cos_h * cos_h, 0.0))
    cos_phi = np.cos(phi)[None, None, :]
    mu = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)[:, None, None]
    sin_v = np.sqrt(1.0 - mu * mu)
    # V = (sin_v, 0, mu), N = (0, 0, 1), L = 2 (V.h) h - V
    vdoth = sin_v * sin_h * cos_phi + mu * cos_h
    ndotl = 2.0 * vdoth * cos_h - mu
    ok = (vdoth > 0.0) & (ndotl > 0.0)
    # integrand P F (N.L) / (V.h) dw_h = (1/2) F (N.L) / ((V.h) (N.h)) dxi dphi
    integrand = np.where(ok, 0.5 * fresnel_schlick(vdoth, f0) * ndotl / np.where(ok, vdoth * cos_h, 1.0), 0.0)
    # midpoint cells: dxi = 1 / n_xi, dphi = pi / n_phi, doubled for phi in (pi, 2 pi)
    return integrand.sum(axis=(1, 2)) * (2.0 * np.pi / n_phi) / n_xi


@lru_cache(maxsize=4)
def _rho_dt_table_cached(size_cos: int, size_m: int) -> np.ndarray:
    """Built once per process, and kept in dermis's disk cache (geometry.bake_cache: DERMIS_CACHE_DIR, off
    with "off") under a key of the sizes, F0 and the source of this module (which computes it): every
    process that renders needs it (0.6-1.5 s to build on 2 cores; the test suite starts ~20 of them)."""
    import hashlib

    from dermis.geometry import bake_cache

    # this whole module's source: a change to any function the table is built with rebuilds it (None in a
    # frozen build: built, not stored)
    source = bake_cache.source_key(sys.modules[__name__])
    key = hashlib.sha256(repr((size_cos, size_m, SKIN_F0, source)).encode()).hexdigest()
    path = None if source is None else bake_cache.cache_path("rho_dt", key)
    got = bake_cache.load({}, key, path, {"table": (size_m, size_cos)}, 1)
    if got is not None and got["table"].dtype == np.float32:
        table = np.array(got["table"])
    else:
        x = np.arange(size_cos, dtype=np.float64) / (size_cos - 1)
        cos = x * x  # x = sqrt(cos_theta) at texel centres
        table = np.stack([_albedo(cos, float(mj), SKIN_F0, 96, 64) for mj in roughness_axis(size_m)])
        table = table.astype(np.float32)
        bake_cache.store(path, {"table": table})
    table.setflags(write=False)
    return table


def rho_dt_table(size_cos: int = RHO_DT_TABLE_SIZE[0], size_m: int = RHO_DT_TABLE_SIZE[1]):
    """The albedo a(cos, m) of :func:`rho_dt` for rho_s = 1 and F0 = SKIN_F0 (d'Eon & Luebke 2007,
    section 14.3, precompute it with 80 x 80 samples per texel; 96 x 128 importance-sampled nodes here).

    Returns float32 (size_m, size_cos), read-only and cached: column i holds cos_theta = x_i^2 with
    x_i = i / (size_cos - 1); row j holds m_j of :func:`roughness_axis`; both AT TEXEL CENTRES.
    The renderer multiplies by rho_s: diffuse keeps 1 - rho_s * a / pi. Builds in about 0.6 s (64 x 64).
    """
    if size_cos < 2 or size_m < 2:
        raise ValueError("rho_dt_table needs at least 2 x 2 texels")
    return _rho_dt_table_cached(int(size_cos), int(size_m))
