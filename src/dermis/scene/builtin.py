"""Built-in meshes (test primitives and the procedural head) and the built-in default scene.

All primitives carry unique (non-overlapping) UV layouts so that every technique, texture-space
diffusion included, can render them.
"""

from __future__ import annotations

import numpy as np

from dermis.errors import DermisError
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Output, Scene, SkinMaterial, Texture


def grid_mesh(nu: int, nv: int, fn, uv_rect=(0.0, 0.0, 1.0, 1.0)):
    """A (nu x nv)-quad grid: fn(u, v) -> (positions (..,3), normals (..,3)) for u, v in [0, 1].

    Returns positions, normals, uvs (mapped into uv_rect = (u0, v0, u1, v1)) and CCW indices
    (counter-clockwise when dP/du x dP/dv points along the normal).
    """
    u, v = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="xy")
    p, n = fn(u, v)
    u0, v0, u1, v1 = uv_rect
    uv = np.stack([u0 + u * (u1 - u0), v0 + v * (v1 - v0)], -1)
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nv + 1, nu + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return p.reshape(-1, 3), n.reshape(-1, 3), uv.reshape(-1, 2), tris


def merge(parts):
    P, N, UV, I, base = [], [], [], [], 0
    for p, n, uv, t in parts:
        P.append(p), N.append(n), UV.append(uv), I.append(t + base)
        base += len(p)
    return np.concatenate(P), np.concatenate(N), np.concatenate(UV), np.concatenate(I)


def uv_sphere(radius=1.0, nu=96, nv=48):
    def fn(u, v):
        phi, theta = u * 2 * np.pi, v * np.pi  # theta from the south pole
        n = np.stack([np.sin(theta) * np.sin(phi), -np.cos(theta), np.sin(theta) * np.cos(phi)], -1)
        return radius * n, n

    return grid_mesh(nu, nv, fn)


def plane_xy(size=2.0, n=64, uv_rect=(0, 0, 1, 1), z=0.0, size_y=None):
    sy = size if size_y is None else size_y

    def fn(u, v):
        p = np.stack([(u - 0.5) * size, (v - 0.5) * sy, np.full_like(u, z)], -1)
        return p, np.broadcast_to([0.0, 0.0, 1.0], p.shape)

    return grid_mesh(n, n, fn, uv_rect)


def box(center, half, uv_origin=(0.0, 0.0), uv_cell=0.25, n=8, gutter=0.02):
    """An axis-aligned box; each face its own UV island in a 3x2 atlas of cells ``uv_cell`` wide."""
    cx, cy, cz = center
    hx, hy, hz = half
    faces = [  # normal, origin corner, du axis, dv axis (du x dv = normal)
        ((1, 0, 0), (cx + hx, cy - hy, cz + hz), (0, 0, -2 * hz), (0, 2 * hy, 0)),
        ((-1, 0, 0), (cx - hx, cy - hy, cz - hz), (0, 0, 2 * hz), (0, 2 * hy, 0)),
        ((0, 1, 0), (cx - hx, cy + hy, cz + hz), (2 * hx, 0, 0), (0, 0, -2 * hz)),
        ((0, -1, 0), (cx - hx, cy - hy, cz - hz), (2 * hx, 0, 0), (0, 0, 2 * hz)),
        ((0, 0, 1), (cx - hx, cy - hy, cz + hz), (2 * hx, 0, 0), (0, 2 * hy, 0)),
        ((0, 0, -1), (cx + hx, cy - hy, cz - hz), (-2 * hx, 0, 0), (0, 2 * hy, 0)),
    ]
    parts = []
    for i, (nrm, o, du, dv) in enumerate(faces):
        col, row = i % 3, i // 3
        u0, v0 = uv_origin[0] + col * uv_cell + gutter, uv_origin[1] + row * uv_cell + gutter
        rect = (u0, v0, u0 + uv_cell - 2 * gutter, v0 + uv_cell - 2 * gutter)

        def fn(u, v, o=np.array(o, float), du=np.array(du, float), dv=np.array(dv, float), nrm=nrm):
            p = o + u[..., None] * du + v[..., None] * dv
            return p, np.broadcast_to(np.array(nrm, float), p.shape)

        parts.append(grid_mesh(n, n, fn, rect))
    return merge(parts)


def box_over_plane():
    """A 4x4 plane at z = 0 facing +z and a 0.5 x 0.5 x 0.2 box centred 0.5 above it."""
    plane = plane_xy(4.0, 64, uv_rect=(0.02, 0.02, 0.48, 0.98))
    b = box((0.0, 0.0, 0.5), (0.25, 0.25, 0.1), uv_origin=(0.5, 0.0), uv_cell=1 / 6)
    return merge([plane, b])


def cylinder_seam(radius=1.0, height=3.0, nu=128, nv=32, seam_angle=0.0):
    """An open cylinder along y whose UV seam (u = 0 = 1) lies at azimuth ``seam_angle`` (radians
    from +z towards +x), so a light and camera on +z see the seam across the lit side."""

    def fn(u, v):
        a = seam_angle + u * 2 * np.pi
        n = np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], -1)
        p = n * radius + np.stack([np.zeros_like(v), (v - 0.5) * height, np.zeros_like(v)], -1)
        return p, n

    p, n, uv, t = grid_mesh(nu, nv, fn, uv_rect=(0.02, 0.02, 0.98, 0.98))
    return p, n, uv, t


def slab(size=20.0, thickness=1.0, n=32):
    """A square slab in x-y, ``thickness`` along z (front face z = +t/2 faces +z), closed."""
    return box((0.0, 0.0, 0.0), (size / 2, size / 2, thickness / 2), uv_origin=(0.0, 0.0), uv_cell=1 / 3, n=n, gutter=0.01)


def _head(source):
    from dermis.scene.procedural_head import build_default_head

    h = build_default_head()
    mesh = finish_mesh(h.positions, h.normals, h.uvs, h.indices, "builtin:default_head", "v-up")
    mat = SkinMaterial(albedo=Texture(h.albedo, "builtin:default_head albedo"),
                       normal_map=Texture(h.normal_map, "builtin:default_head normals"),
                       specular_map=Texture(h.specular[:, :, None], "builtin:default_head specular"))
    return mesh, mat, float(h.mm_per_unit)


BUILTINS = {
    "default_head": None,
    "sphere": lambda: uv_sphere(),
    "plane": lambda: plane_xy(),
    "box_over_plane": box_over_plane,
    "cylinder_seam": lambda: cylinder_seam(),
    "slab": lambda: slab(),
}


def builtin_mesh(name: str, source="builtin"):
    """Returns (Mesh, SkinMaterial or None, default mm_per_unit)."""
    if name not in BUILTINS:
        raise DermisError(f"{source}: unknown builtin mesh '{name}' (one of {', '.join(BUILTINS)})")
    if name == "default_head":
        return _head(source)
    p, n, uv, t = BUILTINS[name]()
    return finish_mesh(p, n, uv, t, f"builtin:{name}", "v-up"), None, 10.0


def frame_camera(scene: Scene, azimuth_deg: float = 0.0, elevation_deg: float = 5.0, fill: float = 1.15):
    """Point the camera at the mesh's bounding sphere from the front (+z), fitting it in view."""
    lo, hi = scene.bounds()
    c = (lo + hi) / 2
    r = float(np.linalg.norm(hi - lo) / 2)
    fov = np.radians(scene.camera.fov_deg)
    dist = fill * r / np.sin(fov / 2)
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    d = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    scene.camera.position = tuple(c + d * dist)
    scene.camera.target = tuple(c)
    scene.camera.fit = True  # the render fits the mesh exactly for its aspect (dermis.framing)


def default_lights(scene: Scene):
    """Three-point lighting around the mesh: warm key (upper left front), cool fill, rim from behind."""
    lo, hi = scene.bounds()
    c = (lo + hi) / 2
    r = float(np.linalg.norm(hi - lo) / 2)

    def toward(p):
        d = c - np.asarray(p)
        return tuple(d / np.linalg.norm(d))

    key_pos = c + r * np.array([-1.6, 1.2, 2.2])
    fill_pos = c + r * np.array([2.5, 0.2, 1.4])
    rim_pos = c + r * np.array([1.2, 0.8, -2.5])
    scene.lights = [
        Light(kind="directional", color=(1.0, 0.93, 0.85), intensity=3.2, direction=toward(key_pos), position=tuple(key_pos)),
        Light(kind="directional", color=(0.75, 0.85, 1.0), intensity=0.6, direction=toward(fill_pos), position=tuple(fill_pos), shadow_softness=3.0),
        Light(kind="directional", color=(1.0, 0.95, 0.9), intensity=1.5, direction=toward(rim_pos), position=tuple(rim_pos)),
    ]


def frame_scene(scene: Scene):
    frame_camera(scene)
    default_lights(scene)


def default_scene() -> Scene:
    """The built-in scene: the procedural head under three-point light. Needs no files."""
    mesh, mat, mm = _head("builtin")
    scene = Scene(mesh=mesh, material=mat, mm_per_unit=mm, camera=Camera(fov_deg=28.0),
                  environment=Environment(color=(0.035, 0.035, 0.04)), output=Output(), source="builtin:default",
                  name="default")
    frame_camera(scene, azimuth_deg=25.0, elevation_deg=6.0, fill=0.95)
    default_lights(scene)
    return scene
