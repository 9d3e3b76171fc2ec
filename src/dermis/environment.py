"""Environment lighting as spherical-harmonic irradiance (Ramamoorthi & Hanrahan 2001).

Equirectangular convention: row 0 is straight up (+y); u = 0.5 + atan2(x, -z) / (2 pi), so the
image centre looks along -z. The 9 coefficients returned are A_l * L_lm (irradiance), ready for
common/environment.glsl.
"""

from __future__ import annotations

import math

import numpy as np

# cosine-lobe convolution constants A_l (Ramamoorthi & Hanrahan 2001, eq. 8)
_A = np.array([np.pi, 2 * np.pi / 3, 2 * np.pi / 3, 2 * np.pi / 3, np.pi / 4, np.pi / 4, np.pi / 4, np.pi / 4, np.pi / 4])


def sh9_basis(d):
    """Real SH basis Y_lm for l <= 2 at unit directions d (..., 3), in the order the shader uses."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([
        np.full_like(x, 0.282095), 0.488603 * y, 0.488603 * z, 0.488603 * x,
        1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1), 1.092548 * x * z,
        0.546274 * (x * x - y * y)], -1)


def equirect_directions(h, w):
    theta = (np.arange(h) + 0.5) / h * np.pi  # from +y
    phi = ((np.arange(w) + 0.5) / w - 0.5) * 2 * np.pi
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(th) * np.sin(ph), np.cos(th), -np.sin(th) * np.cos(ph)], -1)
    d_omega = (np.pi / h) * (2 * np.pi / w) * np.sin(th)
    return d, d_omega


def sh_irradiance_from_equirect(img) -> np.ndarray:
    """(9, 3) irradiance SH coefficients A_l L_lm from a linear equirect radiance image."""
    from dermis.images import as_rgb

    img = as_rgb(img).astype(np.float64)
    d, dw = equirect_directions(*img.shape[:2])
    Y = sh9_basis(d)  # (h, w, 9)
    L = np.einsum("hwk,hwc,hw->kc", Y, img, dw)
    return (_A[:, None] * L).astype(np.float32)


def sh_irradiance_constant(rgb) -> np.ndarray:
    """A constant radiance c everywhere gives irradiance pi * c for every normal."""
    out = np.zeros((9, 3), np.float32)
    out[0] = np.pi * np.asarray(rgb, np.float64) / 0.282095
    return out


def irradiance_sh_eval(coeffs, n):
    """E(n) from the 9 coefficients (numpy twin of environment_irradiance())."""
    return np.maximum(sh9_basis(np.asarray(n, np.float64)) @ np.asarray(coeffs, np.float64), 0.0)


def rotate_equirect(image: np.ndarray, degrees: float) -> np.ndarray:
    """An equirectangular image (row 0 = up, centre = -z; this module's convention) turned
    by ``degrees`` about +y: what was seen along direction d is then seen along R_y(degrees) d.

    With u = 0.5 + atan2(x, -z) / 2 pi, R_y(theta) moves a feature from u to u - theta / 2 pi,
    so column u of the result samples the source at u + theta / 2 pi, linearly interpolated
    between columns (periodic in u); a multiple of 360 / width is an exact column shift."""
    img = np.asarray(image, np.float32)
    w = img.shape[1]
    shift = (float(degrees) / 360.0) * w  # in columns
    whole = math.floor(shift)
    frac = shift - whole
    a = np.roll(img, -whole, axis=1)
    if frac < 1e-9:
        return a
    b = np.roll(img, -(whole + 1), axis=1)
    return ((1.0 - frac) * a + frac * b).astype(np.float32)


def equirect_radiance(env) -> np.ndarray:
    """The environment's equirect image as every consumer must see it (SH, the prefiltered
    specular, the reference, the Blender export's mapping): turned by ``env.rotation_deg`` about
    +y. Not scaled by the intensity. ``env.image`` must not be None."""
    if not float(env.rotation_deg) % 360.0:
        return env.image.data
    return rotate_equirect(env.image.data, float(env.rotation_deg))


def environment_sh(env) -> np.ndarray:
    if env.image is not None:
        from dermis.invalidation import memo_by_content, read_only

        # projected once per image content and rotation: LightUniforms asks on every light change
        sh = memo_by_content("environment_sh", (env.image.data,), float(env.rotation_deg),
                             lambda: read_only(sh_irradiance_from_equirect(equirect_radiance(env))))
        return sh * env.intensity
    return sh_irradiance_constant(env.color) * env.intensity


def environment_is_black(env) -> bool:
    """True for a constant environment of no light (colour x intensity 0, no image): its occlusion,
    diffuse (r E_sh) and specular (E_sh(R) rho_s a so / pi) are 0 whatever the mesh blocks, so the
    renderers skip the ambient-occlusion bake and rays (the same image, bit for bit)."""
    return env.image is None and not np.any(environment_sh(env) != 0.0)
