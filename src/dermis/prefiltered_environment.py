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

Layers (one 3-D texture, shaders/common/environment.glsl ``environment_specular``): LAYERS maps of
HEIGHT x WIDTH texels, layer k holding Lpref for the Beckmann roughness
m_k = M_MIN (M_MAX / M_MIN)^(k / (LAYERS - 1)), the same log axis as the specular tables, so the
shader's third coordinate is the tables' roughness coordinate y(m) at texel centres and the
hardware's trilinear filter interpolates linearly in log m between neighbouring layers (a
ratio of 1.22 in m; a mip chain, whose levels must halve the resolution, allowed only six levels
over [0.05, 1] and blending two lobes 1.8x apart in m was up to 8 % off the lobe between them).
The lobe's standard deviation about R is about sqrt(2) m radians: 2.9 texels at m = 0.05.

Equirect convention: dermis.environment's (row 0 = +y, u = 0.5 + atan2(x, -z) / 2 pi), so the
specular and the diffuse SH see the environment in the same orientation.

Cost (numpy, one core): about 2-3 s per environment (the convolution of each layer is a product of
FFTs along each row, restricted to the rows the lobe reaches); cached per image content in this
process and, in the Renderer, as the PRODUCTS entry "environment_specular".

GGX users (glTF metallic-roughness): the layers hold BECKMANN lobes. Passing GGX alpha as m gives
a lobe of the same width at the peak (Walter et al. 2007, sec. 5.2: alpha_GGX ~ m_Beckmann), but
GGX's long tail is missing, so a rough GGX reflection of a bright source is slightly too tight
and its far tail too dark.
"""

from __future__ import annotations

import numba
import numpy as np

from dermis.specular import M_MAX, M_MIN, SKIN_F0, beckmann_ndf, fresnel_schlick, roughness_to_y

LAYERS = 16
"""Prefiltered roughness layers (the 3-D texture's depth)."""
HEIGHT, WIDTH = 128, 256
"""Texels of every layer (equirect, 1.4 degrees a texel)."""
KERNEL_CUTOFF = 40.0
"""The kernel is dropped where tan^2(g / 2) / m^2 > 40, i.e. where it is below e^-40 of its peak."""


def layer_roughness(k) -> np.ndarray:
    """Beckmann m of layer k: M_MIN (M_MAX / M_MIN)^(k / (LAYERS - 1))."""
    return M_MIN * (M_MAX / M_MIN) ** (np.asarray(k, np.float64) / (LAYERS - 1))


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


KERNEL_TABLE_SIZE = 8193
"""Samples of each layer's kernel over x = sqrt(1 - cos g) in [0, 1] (the Beckmann table's axis,
where the lobe is about a Gaussian of width m / 2): linear interpolation is within 1e-6 of the
closed form relative to the peak (tests/test_environment_specular.py)."""


def kernel_table(m: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, K_m(1 - x^2)) on KERNEL_TABLE_SIZE points of x in [0, 1]."""
    x = np.linspace(0.0, 1.0, KERNEL_TABLE_SIZE)
    return x, lobe_kernel(1.0 - x * x, m)


@numba.njit(cache=True, parallel=True)
def _kernel_rows(tables, ct_o, st_o, ct_r, st_r, cos_dphi):
    """K of every layer between one output row and the source rows (layers, rows, w): linear
    interpolation of each layer's kernel table (uniform in x = sqrt(1 - cos g)) at
    cos g = cos t_o cos t_s + sin t_o sin t_s cos(dphi)."""
    n_layers, n1 = tables.shape
    n = n1 - 1
    out = np.empty((n_layers, len(ct_r), len(cos_dphi)))
    for j in numba.prange(len(ct_r)):
        for q in range(len(cos_dphi)):
            cg = ct_o * ct_r[j] + st_o * st_r[j] * cos_dphi[q]
            t = min(np.sqrt(max(1.0 - cg, 0.0)), 1.0 + 1.0 / (n - 1)) * (n - 1)
            i0 = min(int(t), n - 1)
            f = t - i0
            for layer in range(n_layers):
                out[layer, j, q] = tables[layer, i0] * (1.0 - f) + tables[layer, i0 + 1] * f
    return out


def prefilter_layers(src, ms) -> np.ndarray:
    """Lpref of an equirect radiance image (h, w, 3) for each roughness of ``ms``, on the same
    grid: (len(ms), h, w, 3). The convolution with K_m as a quadrature over the texel centres
    (solid-angle weights); per output row a circular convolution along phi done with FFTs, over
    the rows the lobe reaches (K below e^-40 of its peak is dropped); K from :func:`kernel_table`."""
    src = np.asarray(src, np.float64)
    h, w = src.shape[:2]
    ms = [float(m) for m in ms]
    theta = (np.arange(h) + 0.5) / h * np.pi
    st, ct = np.sin(theta), np.cos(theta)
    d_omega = (np.pi / h) * (2 * np.pi / w) * st
    f_src = np.fft.rfft(src * d_omega[:, None, None], axis=1)  # (h, w/2+1, 3)
    cos_dphi = np.cos(2 * np.pi * np.arange(w) / w)
    n = KERNEL_TABLE_SIZE
    # each layer's kernel table, padded with a 0 past x = 1 (cos g < 0: below the lobe's horizon)
    tables = np.zeros((len(ms), n + 1))
    for i, m in enumerate(ms):
        tables[i, :n] = kernel_table(m)[1]
    g_max = max(min(np.pi / 2, 2.0 * np.arctan(m * np.sqrt(KERNEL_CUTOFF))) for m in ms)
    out = np.empty((len(ms), h, w, 3))
    for o in range(h):
        rows = np.nonzero(np.abs(theta - theta[o]) <= g_max + 1e-12)[0]
        k = _kernel_rows(tables, ct[o], st[o], ct[rows], st[rows], cos_dphi)  # (layers, rows, w)
        fk = np.fft.rfft(k, axis=2)  # (layers, rows, w/2+1)
        # per frequency: sum over rows of FK * F_src, as one batched matrix product
        prod = np.matmul(fk.transpose(2, 0, 1), f_src[rows].transpose(1, 0, 2))  # (w/2+1, layers, 3)
        num = np.fft.irfft(prod, n=w, axis=0)  # (w, layers, 3)
        den = np.einsum("lrw,r->l", k, d_omega[rows])
        out[:, o] = num.transpose(1, 0, 2) / den[:, None, None]
    return out


def prefilter_layer(src, m: float) -> np.ndarray:
    """:func:`prefilter_layers` for one roughness: (h, w, 3)."""
    return prefilter_layers(src, [m])[0]


_CACHE: dict = {}
"""fingerprint of an image -> its layers (the last 4 environments)."""


def prefilter_equirect(img) -> np.ndarray:
    """The LAYERS prefiltered maps of a linear equirect radiance image (H, W, >= 3): float32
    (LAYERS, HEIGHT, WIDTH, 3), read-only; cached per image content (the last 4)."""
    from dermis.images import as_rgb
    from dermis.invalidation import fingerprint

    img = as_rgb(img)
    key = fingerprint(img)
    if key not in _CACHE:
        src = resample_equirect(img, HEIGHT, WIDTH)
        layers = prefilter_layers(src, layer_roughness(np.arange(LAYERS))).astype(np.float32)
        layers.setflags(write=False)
        while len(_CACHE) >= 4:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = layers
    return _CACHE[key]


def environment_specular_layers(env) -> np.ndarray:
    """What the GPU's environment-specular texture holds for a scene Environment, (layers, h, w, 3)
    float32: the prefiltered layers of its image times its intensity, or one 1 x 1 layer of its
    constant colour (a constant environment needs no prefilter: Lpref is the constant for every
    lobe)."""
    if env.image is None:
        return (np.asarray(env.color, np.float32) * np.float32(env.intensity)).reshape(1, 1, 1, 3)
    from dermis.environment import equirect_radiance

    return prefilter_equirect(equirect_radiance(env)) * np.float32(env.intensity)


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
    # at the poles (x = z = 0) u = 0.5, as the shader (GLSL leaves atan(0, 0) undefined)
    pole = (d[..., 0] == 0.0) & (d[..., 2] == 0.0)
    u = 0.5 + np.where(pole, 0.0, np.arctan2(d[..., 0], -d[..., 2])) / (2 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return u, v


def specular_dominant_direction(N, R, m) -> np.ndarray:
    """Numpy twin of specular_dominant_direction() (common/environment.glsl): R bent towards N
    (Lagarde & de Rousiers 2014, sec. 4.9.3, listing 22, with alpha = Beckmann m)."""
    s = np.clip(1.0 - np.asarray(m, np.float64), 0.0, 1.0)
    f = np.asarray(s * (np.sqrt(s) + m))[..., None] if np.ndim(m) else s * (np.sqrt(s) + m)
    d = np.asarray(N, np.float64) + (np.asarray(R, np.float64) - N) * f
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


SKIN_ENV_GRAZING_EXPONENT = 0.8
"""skin_environment_specular's lobe narrowing: m_eff = m (N.V)^0.8 (common/environment.glsl)."""


def skin_environment_specular(layers, N, V, m) -> np.ndarray:
    """Numpy twin of skin_environment_specular(N, V, m) (common/environment.glsl): the layers
    along R = reflect(-V, N) at m (N.V)^0.8. (n, 3)."""
    N = np.asarray(N, np.float64).reshape(-1, 3)
    V = np.asarray(V, np.float64).reshape(-1, 3)
    ndv = np.clip(np.sum(N * V, -1), 1e-4, 1.0)
    R = 2.0 * ndv[:, None] * N - V
    m_eff = np.asarray(m, np.float64) * ndv ** SKIN_ENV_GRAZING_EXPONENT
    return sample_environment_specular(layers, R, m_eff)


def sample_environment_specular(layers, R, m) -> np.ndarray:
    """Numpy twin of environment_specular(R, m) (shaders/common/environment.glsl): bilinear in each
    layer, linear between the two layers around y(m) (texel centres, clamped). (n, 3)."""
    layers = np.asarray(layers, np.float64)
    R = np.asarray(R, np.float64).reshape(-1, 3)
    u, v = direction_to_equirect(R)
    z = np.clip((len(layers) - 1) * np.broadcast_to(roughness_to_y(m), (len(R),)), 0.0, len(layers) - 1.0)
    k0 = np.minimum(np.floor(z).astype(np.int64), max(len(layers) - 2, 0))
    k1 = np.minimum(k0 + 1, len(layers) - 1)
    t = (z - k0)[:, None]
    res = np.zeros((len(R), 3))
    for k in np.unique(np.concatenate([k0, k1])):
        val = bilinear_equirect(layers[k], u, v)
        res += np.where((k0 == k)[:, None], val * (1 - t), 0.0) + np.where((k1 == k)[:, None], val * t, 0.0)
    return res
