"""The environment's specular: an equirect HDR prefiltered for the skin's specular lobe (numpy, no GL).

What it is: the split-sum approximation of Karis 2013 ("Real Shading in Unreal Engine 4", SIGGRAPH
course notes, eq. 3-5) for the Kelemen & Szirmay-Kalos / Beckmann BRDF of dermis.specular:

    integral L(l) f(l, v) (n.l) dl  ~=  Lpref(R, m) * integral f(l, v) (n.l) dl
                                     =  Lpref(R, m) * rho_s a(n.v, m) / pi        (a: the rho_dt table)

    Lpref(R, m) = integral L(l) K_m(R.l) dl / integral K_m(R.l) dl,
    K_m(cos g)  = f_KSK(l, v = n = R) (R.l) = P(h) F(R.h) (R.l) / |l + R|^2,  R.h = cos(g / 2),

i.e. the environment weighted by the BRDF lobe itself for a view along the normal (Karis's
n = v = R assumption). The kernel depends only on the angle g between l and R (a zonal kernel),
so the prefilter is an exact spherical convolution; it is exact at normal incidence and for a
constant environment (Lpref = the constant, then the product is the integral to the rho_dt
table's accuracy). Away from normal incidence the real lobe stretches and shifts off R; that is
the approximation's error, which ``dermis validate`` measures against the reference's Monte Carlo
integral of the true BRDF (dermis.reference.shading).

Levels (one texture's mip chain, shaders/common/environment.glsl ``environment_specular``):
level k is BASE_HEIGHT / 2^k x BASE_WIDTH / 2^k texels and holds Lpref for the Beckmann roughness
m_k = M_MIN (M_MAX / M_MIN)^(k / (LEVELS - 1)), the same log axis as the specular tables, so the
shader's lod is (LEVELS - 1) * y(m) and trilinear filtering interpolates in log m. The lobe's
standard deviation about R is about sqrt(2) m radians; it spans >= 3.6 texels at every level.

Equirect convention: dermis.environment's (row 0 = +y, u = 0.5 + atan2(x, -z) / 2 pi), so the
specular and the diffuse SH see the environment in the same orientation.

Cost (numpy, one core): about 1-3 s per environment (the convolution of each level is a product of
FFTs along each row, restricted to the rows the lobe reaches); cached per image content in this
process and, in the Renderer, as the PRODUCTS entry "environment_specular".

GGX users (glTF metallic-roughness): the levels hold BECKMANN lobes. Passing GGX alpha as m gives
a lobe of the same width at the peak (Walter et al. 2007, sec. 5.2: alpha_GGX ~ m_Beckmann), but
GGX's long tail is missing, so a rough GGX reflection of a bright source is slightly too tight
and its far tail too dark.
"""

from __future__ import annotations

import numpy as np

from dermis.specular import M_MAX, M_MIN, SKIN_F0, beckmann_ndf, fresnel_schlick, roughness_to_y

LEVELS = 6
"""Prefiltered levels (mip levels 0 .. LEVELS - 1)."""
BASE_WIDTH = 512
"""Width of level 0 (its height is half of it): the m = M_MIN lobe spans 5.8 texels per sigma."""
KERNEL_CUTOFF = 40.0
"""The kernel is dropped where tan^2(g / 2) / m^2 > 40, i.e. where it is below e^-40 of its peak."""


def level_roughness(k) -> np.ndarray:
    """Beckmann m of level k: M_MIN (M_MAX / M_MIN)^(k / (LEVELS - 1))."""
    return M_MIN * (M_MAX / M_MIN) ** (np.asarray(k, np.float64) / (LEVELS - 1))


def level_shape(k: int) -> tuple[int, int]:
    """(height, width) of level k."""
    w = BASE_WIDTH >> k
    return w // 2, w


def lobe_kernel(cos_g, m, f0: float = SKIN_F0) -> np.ndarray:
    """K_m(cos g) = P(h) F(R.h) cos g / |l + R|^2 for a light at angle g from R = n = v, with
    R.h = cos(g / 2) and |l + R|^2 = 2 (1 + cos g); 0 where cos g <= 0 (the KSK BRDF of
    dermis.specular with n = v, no rho_s)."""
    c = np.asarray(cos_g, np.float64)
    ch = np.sqrt(np.clip((1.0 + c) * 0.5, 0.0, 1.0))
    k = beckmann_ndf(ch, m) * fresnel_schlick(ch, f0) * c / np.maximum(2.0 * (1.0 + c), 1e-300)
    return np.where(c > 0.0, k, 0.0)


def _interval_overlap(n_out: int, n_in: int) -> np.ndarray:
    """(n_out, n_in) lengths of overlap of n_out and n_in equal cells of [0, 1]."""
    eo = np.arange(n_out + 1) / n_out
    ei = np.arange(n_in + 1) / n_in
    lo = np.maximum(eo[:-1, None], ei[None, :-1])
    hi = np.minimum(eo[1:, None], ei[None, 1:])
    return np.maximum(hi - lo, 0.0)


def resample_equirect(img, h: int, w: int) -> np.ndarray:
    """Exact solid-angle-weighted resampling of a piecewise-constant equirect image to (h, w):
    each output texel is the mean radiance over its solid angle (up or down, any ratio)."""
    img = np.asarray(img, np.float64)
    H, W = img.shape[:2]
    if (H, W) == (h, w):
        return img.copy()
    # rows: overlap in theta weighted by sin(theta): integral of sin over the overlap
    eo = np.arange(h + 1) / h * np.pi
    ei = np.arange(H + 1) / H * np.pi
    lo = np.maximum(eo[:-1, None], ei[None, :-1])
    hi = np.minimum(eo[1:, None], ei[None, 1:])
    rows = np.where(hi > lo, np.cos(lo) - np.cos(np.maximum(hi, lo)), 0.0)
    cols = _interval_overlap(w, W)
    out = np.einsum("lk,ikc->ilc", cols, np.einsum("ij,jkc->ikc", rows, img))
    return out / (rows.sum(1)[:, None, None] * cols.sum(1)[None, :, None])


def prefilter_level(src, m: float) -> np.ndarray:
    """Lpref of an equirect radiance image (h, w, 3) for roughness m, on the same grid: the
    convolution with K_m as a quadrature over the texel centres (solid angle weights), per
    output row a circular convolution along phi done with FFTs."""
    src = np.asarray(src, np.float64)
    h, w = src.shape[:2]
    theta = (np.arange(h) + 0.5) / h * np.pi
    st, ct = np.sin(theta), np.cos(theta)
    d_omega = (np.pi / h) * (2 * np.pi / w) * st
    f_src = np.fft.rfft(src * d_omega[:, None, None], axis=1)  # (h, w/2+1, 3)
    cos_dphi = np.cos(2 * np.pi * np.arange(w) / w)
    g_max = min(np.pi / 2, 2.0 * np.arctan(m * np.sqrt(KERNEL_CUTOFF)))
    out = np.empty((h, w, 3))
    for o in range(h):
        rows = np.nonzero(np.abs(theta - theta[o]) <= g_max + 1e-12)[0]
        cg = ct[o] * ct[rows, None] + st[o] * st[rows, None] * cos_dphi[None, :]
        k = lobe_kernel(cg, m)
        num = np.fft.irfft(np.einsum("rf,rfc->fc", np.fft.rfft(k, axis=1), f_src[rows]), n=w, axis=0)
        out[o] = num / np.sum(k * d_omega[rows, None])
    return out


_CACHE: dict = {}
"""fingerprint of an image -> its levels (the last 4 environments)."""


def prefilter_equirect(img) -> tuple:
    """The LEVELS prefiltered levels of a linear equirect radiance image (H, W, >= 3), float32
    (h_k, w_k, 3), read-only; cached per image content (the last 4)."""
    from dermis.images import as_rgb
    from dermis.invalidation import fingerprint

    img = as_rgb(img)
    key = fingerprint(img)
    if key not in _CACHE:
        levels = []
        for k in range(LEVELS):
            h, w = level_shape(k)
            lv = prefilter_level(resample_equirect(img, h, w), float(level_roughness(k))).astype(np.float32)
            lv.setflags(write=False)
            levels.append(lv)
        while len(_CACHE) >= 4:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = tuple(levels)
    return _CACHE[key]


def environment_specular_levels(env) -> tuple:
    """What the GPU's environment-specular texture holds for a scene Environment: the prefiltered
    levels of its image times its intensity, or a single 1 x 1 level of its constant colour (a
    constant environment needs no prefilter: Lpref is the constant for every lobe)."""
    if env.image is None:
        c = np.asarray(env.color, np.float32) * np.float32(env.intensity)
        return (c.reshape(1, 1, 3),)
    s = np.float32(env.intensity)
    return tuple(lv * s for lv in prefilter_equirect(env.image.data))


# ---------------------------------------------------------------------- lookup (numpy twin)
def bilinear_equirect(level, u, v):
    """GL_LINEAR of an equirect level: u repeats, v clamps; row 0 at v = 0 (the top, +y)."""
    h, w = level.shape[:2]
    x = u * w - 0.5
    y = np.clip(v * h - 0.5, 0.0, h - 1.0)
    x0 = np.floor(x)
    y0 = np.minimum(np.floor(y), max(h - 2, 0))
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y0 = y0.astype(np.int64)
    y1 = np.minimum(y0 + 1, h - 1)
    top = level[y0, x0] * (1 - fx) + level[y0, x1] * fx
    bot = level[y1, x0] * (1 - fx) + level[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def direction_to_equirect(d):
    """(u, v) of unit directions (..., 3): u = 0.5 + atan2(x, -z) / 2 pi, v = acos(y) / pi (v = 0 up)."""
    d = np.asarray(d, np.float64)
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return u, v


def sample_environment_specular(levels, R, m) -> np.ndarray:
    """Numpy twin of environment_specular(R, m) (shaders/common/environment.glsl): trilinear
    lookup, lod = (levels - 1) * y(m) on the specular tables' log-roughness axis. (n, 3)."""
    R = np.asarray(R, np.float64).reshape(-1, 3)
    u, v = direction_to_equirect(R)
    lod = (len(levels) - 1) * np.broadcast_to(roughness_to_y(m), (len(R),))
    k0 = np.clip(np.floor(lod).astype(np.int64), 0, len(levels) - 1)
    k1 = np.minimum(k0 + 1, len(levels) - 1)
    t = (lod - k0)[:, None]
    res = np.zeros((len(R), 3))
    for k in np.unique(np.concatenate([k0, k1])):
        val = bilinear_equirect(np.asarray(levels[k], np.float64), u, v)
        res += np.where((k0 == k)[:, None], val * (1 - t), 0.0) + np.where((k1 == k)[:, None], val * t, 0.0)
    return res
