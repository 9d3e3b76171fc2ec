"""Adaptive texture resolution: irradiance and shadow texture sizes from the mesh's size on screen.

d'Eon & Luebke 2007 (GPU Gems 3, 14.4.1) choose the irradiance texture's resolution from the
face's size on screen: a texel much larger than a pixel shows as blocks (a shadow edge rendered
into the irradiance texture becomes a staircase), a texel much smaller is work nobody sees. Here:

  pixels per mm at the mesh     p = H / (2 z tan(fov / 2) mm_per_unit)
      (H the frame's height in pixels, z the view depth of the mesh's bounding-box centre in
      scene units, fov the vertical field of view: a surface facing the camera at depth z)
  layout density                rho = area-weighted median over triangles of sqrt(A_uv / A_mm)
      (texture-space texels per mm per texel of texture size: S rho texels per mm at size S)
  irradiance size               S = 2^ceil(log2(p / (2 rho))),    clamped to IRRADIANCE_RANGE
      (at least one texel per two pixels where the skin faces the camera: the irradiance is
      read with bilinear filtering and blurred by the profile, so a texel of two pixels shows no
      steps, while four pixels per texel (the viewer's former fixed 512 on the head) showed the
      nose shadow's staircase; one texel per pixel would cost 4x the texels for little)
  shadow tile size              T = 2^ceil(log2(p D)),            clamped to SHADOW_RANGE
      (a directional light's tile spans at most the mesh's bounding diameter D mm, so its
      texels' footprint on the skin, D / T mm, is at most a pixel; PCF softens the rest)

Only when the scene or the caller does not fix a size (``Renderer(irradiance_size=None)``,
``dermis view`` without ``--irradiance-size`` / ``--shadow-size``, where the sizes follow the view as it
zooms: viewer/app.py re-chooses them at each full-quality frame); an explicit size always wins.
"""

from __future__ import annotations

import math

import numpy as np

IRRADIANCE_RANGE = (256, 2048)
SHADOW_RANGE = (512, 4096)
IRRADIANCE_TEXELS_PER_PIXEL = 0.5
SHADOW_TEXELS_PER_PIXEL = 1.0


def pow2_at_least(x: float, lo: int, hi: int) -> int:
    """The smallest power of two >= x, clamped to [lo, hi]."""
    n = 1 << max(0, math.ceil(math.log2(max(float(x), 1.0))))
    return int(min(max(n, lo), hi))


def pixels_per_mm(camera, positions, size, mm_per_unit: float) -> float:
    """Screen pixels per mm of a surface facing the camera at the depth of the bounding-box centre
    of ``positions`` (scene units), for a frame of ``size`` = (W, H)."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    c = (p.min(axis=0) + p.max(axis=0)) / 2
    eye = np.asarray(camera.position, np.float64)
    f = np.asarray(camera.target, np.float64) - eye
    f /= max(np.linalg.norm(f), 1e-12)
    z = max(float((c - eye) @ f), 1e-6)
    return size[1] / (2.0 * z * math.tan(math.radians(camera.fov_deg) / 2) * float(mm_per_unit))


def layout_density(positions, uvs, indices, mm_per_unit: float) -> float:
    """rho: the area-weighted median over triangles of sqrt(uv area / surface area in mm^2), i.e.
    texels per mm per texel of texture size."""
    p = np.asarray(positions, np.float64) * float(mm_per_unit)
    uv = np.asarray(uvs, np.float64)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    a3 = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    e1, e2 = uv[t[:, 1]] - uv[t[:, 0]], uv[t[:, 2]] - uv[t[:, 0]]
    a2 = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    ok = (a3 > 0) & (a2 > 0)
    if not ok.any():
        return 0.0
    d, w = np.sqrt(a2[ok] / a3[ok]), a3[ok]
    order = np.argsort(d)
    cw = np.cumsum(w[order])
    return float(d[order][np.searchsorted(cw, 0.5 * cw[-1])])


_MESH_MEASURES: list = []  # [(mesh, uvs, mm_per_unit, (rho, diameter_mm))]: the last mesh measured


def mesh_measures(mesh, mm_per_unit: float) -> tuple[float, float]:
    """(rho, bounding diameter in mm) of ``mesh``: what adaptive_sizes needs of the mesh, the same for
    every view (rho costs ~0.1 s on the head); the last mesh's are remembered (the viewer asks at
    every full-quality frame)."""
    uv = mesh.uvs if getattr(mesh, "texture_space_uvs", None) is None else mesh.texture_space_uvs
    for m, u, mm, measures in _MESH_MEASURES:
        if m is mesh and u is uv and mm == float(mm_per_unit):
            return measures
    rho = layout_density(mesh.positions, uv, mesh.indices, mm_per_unit)
    pos = np.asarray(mesh.positions, np.float64)
    diameter_mm = float(np.linalg.norm(pos.max(axis=0) - pos.min(axis=0))) * float(mm_per_unit)
    _MESH_MEASURES[:] = [(mesh, uv, float(mm_per_unit), (rho, diameter_mm))]
    return rho, diameter_mm


def adaptive_sizes(scene, size, camera=None) -> tuple[int, int]:
    """(irradiance size, shadow tile size) for ``scene`` seen in a frame of ``size`` = (W, H)
    through ``camera`` (default: the scene's camera, framed as ``dermis render`` frames it): the
    rule of this module's docstring."""
    from dermis.framing import framed_camera

    m = scene.mesh
    camera = framed_camera(scene.camera if camera is None else camera, m, size[0] / size[1])  # as Renderer.render
    p = pixels_per_mm(camera, m.positions, size, scene.mm_per_unit)
    rho, diameter_mm = mesh_measures(m, scene.mm_per_unit)
    irr = pow2_at_least(IRRADIANCE_TEXELS_PER_PIXEL * p / rho, *IRRADIANCE_RANGE) if rho > 0 else IRRADIANCE_RANGE[1]
    shadow = pow2_at_least(SHADOW_TEXELS_PER_PIXEL * p * diameter_mm, *SHADOW_RANGE)
    return irr, shadow
