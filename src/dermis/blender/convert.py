"""dermis -> Blender conventions (pure numpy; no bpy).

Space: dermis is y-up (OpenGL) in scene units; Blender is z-up in metres (its default unit, and
the unit Cycles' light falloff and subsurface radius use). A dermis point p maps to
``metres_per_unit * C @ p`` with C = (x, y, z) -> (x, -z, y), the rotation glTF importers use, so
the head stands upright in Blender. Cameras and lights look along their local -Z with +Y up in
both, so an orientation R (columns = local axes) maps to C @ R.

Radiometry (dermis radiance is linear physical, diffuse = albedo / pi * E):
* directional: dermis intensity = irradiance at normal incidence (W/m^2) = Blender sun strength;
* point/spot: dermis intensity I is per steradian with inverse-square falloff over metres;
  Cycles' point and spot lights emit I = P / (4 pi) W/sr for power P (a spot is a masked point
  light: its cone does not concentrate the power), so P = 4 pi I;
* spot cone: dermis smoothstep(cos(a), cos(a (1 - b)), cos theta) over the half-angle a and blend
  b; Cycles (kernel/light/spot.h) smoothstep((cos theta - cos a) / ((1 - cos a) b')), so the two
  agree exactly for b' = (cos(a (1 - b)) - cos a) / (1 - cos a).
"""

from __future__ import annotations

import math

import numpy as np

C = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
"""dermis (y-up) -> Blender (z-up) rotation."""


def metres_per_unit(scene) -> float:
    return float(scene.mm_per_unit) * 1e-3


def to_blender_points(p, m_per_unit: float) -> np.ndarray:
    return (np.asarray(p, np.float64) @ C.T) * m_per_unit


def from_blender_points(p, m_per_unit: float) -> np.ndarray:
    return (np.asarray(p, np.float64) / m_per_unit) @ C


def to_blender_dirs(d) -> np.ndarray:
    return np.asarray(d, np.float64) @ C.T


def from_blender_dirs(d) -> np.ndarray:
    return np.asarray(d, np.float64) @ C


def frame_looking_along(forward, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Rotation (columns x, y, z) whose -z is ``forward`` and whose y is as close to ``up`` as
    possible (dermis space). Same fallback as camera.look_at when forward is parallel to up."""
    from dermis.camera import normalize

    f = normalize(forward)
    up = np.asarray(up, np.float64)
    if abs(np.dot(f, normalize(up))) > 0.999:
        up = np.array([0.0, 0.0, 1.0]) if abs(f[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    s = normalize(np.cross(f, up))
    u = np.cross(s, f)
    return np.stack([s, u, -f], axis=1)


def object_matrix(position_units, forward, up, m_per_unit: float) -> np.ndarray:
    """4x4 Blender world matrix of a camera/light at a dermis position looking along ``forward``."""
    m = np.eye(4)
    m[:3, :3] = C @ frame_looking_along(forward, up)
    m[:3, 3] = to_blender_points(position_units, m_per_unit)
    return m


def point_power_w(intensity_w_per_sr: float) -> float:
    """Cycles point/spot power for a dermis intensity (W/sr): P = 4 pi I."""
    return 4.0 * math.pi * float(intensity_w_per_sr)


def point_intensity(power_w: float) -> float:
    return float(power_w) / (4.0 * math.pi)


def spot_blend_cycles(spot_angle_deg: float, spot_blend: float) -> float:
    """Blender spot_blend giving dermis's smoothstep cone (see the module docstring)."""
    a = math.radians(spot_angle_deg)
    co = math.cos(a)
    ci = math.cos(a * (1.0 - spot_blend))
    return float(np.clip((ci - co) / max(1.0 - co, 1e-12), 0.0, 1.0))


def spot_blend_dermis(spot_size_rad: float, blend_cycles: float) -> float:
    """Inverse of spot_blend_cycles for a Blender spot of full cone angle ``spot_size_rad``."""
    a = spot_size_rad / 2
    co = math.cos(a)
    ci = co + blend_cycles * (1.0 - co)
    return float(1.0 - math.acos(min(ci, 1.0)) / a)


def principled_roughness(beckmann_m):
    """Principled BSDF roughness r for a Beckmann slope m: Cycles' GGX alpha = r^2, and a GGX lobe
    with alpha = m has the highlight width of Beckmann m (Walter et al. 2007, sec. 5.2)."""
    return np.sqrt(np.clip(beckmann_m, 0.0, 1.0))


def specular_ior_level(rho_s):
    """Principled 'Specular IOR Level' for dermis rho_s. dermis's Kelemen/Szirmay-Kalos lobe with
    F0 = 0.028 approximates a microfacet BRDF (its 1/|h|^2 term stands for G / (4 N.L N.V)) scaled
    by rho_s; the Principled BSDF with IOR 1.4 (F0 = 0.028) scales F0 by 2 x level."""
    return 0.5 * np.asarray(rho_s, np.float64)


EQUIRECT_ROTATION_Z_DEG = -90.0
"""Mapping-node rotation for equirect environments. dermis: u = 0.5 + atan2(x, -z) / 2pi, row 0 = +y
(environment.py). Blender: u = 0.5 - atan2(y', x') / 2pi, top row = +z. With (x, -z, y) -> Blender,
the lookup direction must be rotated by -90 degrees about z: d' = (d_y, -d_x, d_z)."""


def dermis_equirect_uv(d_dermis) -> np.ndarray:
    d = np.asarray(d_dermis, np.float64)
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    v = 1.0 - np.arccos(np.clip(d[..., 1], -1, 1)) / np.pi  # v = 1 at the top row
    return np.stack([u % 1.0, v], -1)


def equirect_mapping_z_deg(rotation_deg: float = 0.0) -> float:
    """The Mapping node's z rotation for an environment turned by ``rotation_deg`` about dermis's
    +y (Environment.rotation_deg: what was seen along d is seen along R_y(theta) d, so the lookup
    along d reads the image at R_y(-theta) d). dermis +y is Blender +z and the axis change is a
    proper rotation, so R_y(-theta) becomes R_z(-theta), composed with the fixed turn above."""
    return EQUIRECT_ROTATION_Z_DEG - float(rotation_deg)


def blender_equirect_uv(d_blender, rotation_deg: float = 0.0) -> np.ndarray:
    """Cycles' direction_to_equirectangular after the Mapping rotation (v = 1 at the top row)."""
    d = np.asarray(d_blender, np.float64)
    a = np.radians(equirect_mapping_z_deg(rotation_deg))
    x = np.cos(a) * d[..., 0] - np.sin(a) * d[..., 1]
    y = np.sin(a) * d[..., 0] + np.cos(a) * d[..., 1]
    u = 0.5 - np.arctan2(y, x) / (2 * np.pi)
    v = 0.5 + np.arctan2(d[..., 2], np.hypot(x, y)) / np.pi
    return np.stack([u % 1.0, v], -1)
