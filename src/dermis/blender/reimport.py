"""Read a .blend written by dermis.blender.export back into dermis terms (camera, lights, image
paths): the round trip check that an export says what the scene said."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dermis.blender import convert, quiet_fds, require_bpy
from dermis.errors import DermisError
from dermis.scene.model import Camera, Light


def read_blend(path) -> dict:
    """{"mm_per_unit", "camera": Camera, "lights": [Light], "images": {node name: path}}; the
    geometry (camera pose, light direction/position) is recovered from Blender's matrices, the
    rest from the Blender properties (energy, angle, spot size/blend) via dermis.blender.convert."""
    bpy = require_bpy()
    p = Path(path)
    if not p.is_file():
        raise DermisError(f"{p}: no such .blend file")
    with quiet_fds():
        bpy.ops.wm.open_mainfile(filepath=str(p.resolve()))
    sc = bpy.context.scene
    if "dermis_mm_per_unit" not in sc:
        raise DermisError(f"{p}: not written by dermis export (no dermis_mm_per_unit)")
    mpu = float(sc["dermis_mm_per_unit"]) * 1e-3
    cam_o = sc.camera
    m = np.array(cam_o.matrix_world, np.float64)
    pos = convert.from_blender_points(m[:3, 3], mpu)
    fwd = convert.from_blender_dirs(-m[:3, 2])
    up = convert.from_blender_dirs(m[:3, 1])
    dist = float(np.linalg.norm(np.asarray(cam_o["dermis_target"]) - np.asarray(cam_o["dermis_position"])))
    camera = Camera(position=tuple(pos), target=tuple(pos + fwd / np.linalg.norm(fwd) * dist), up=tuple(up),
                    fov_deg=math.degrees(cam_o.data.angle_y))
    lights = []
    for o in sorted((o for o in sc.objects if o.type == "LIGHT"), key=lambda o: o.name):
        ld = o.data
        mw = np.array(o.matrix_world, np.float64)
        d = convert.from_blender_dirs(-mw[:3, 2])
        kind = {"SUN": "directional", "POINT": "point", "SPOT": "spot"}[ld.type]
        L = Light(kind=kind, color=tuple(float(c) for c in ld.color), cast_shadows=bool(ld.use_shadow))
        if kind == "directional":
            L.intensity = float(ld.energy)
            L.direction = tuple(d)
        else:
            L.intensity = convert.point_intensity(ld.energy)
            L.position = tuple(convert.from_blender_points(mw[:3, 3], mpu))
            if kind == "spot":
                L.direction = tuple(d)
                L.spot_angle_deg = math.degrees(ld.spot_size) / 2
                L.spot_blend = convert.spot_blend_dermis(ld.spot_size, ld.spot_blend)
        lights.append(L)
    images = {}
    for mat in bpy.data.materials:
        if mat.node_tree:
            for n in mat.node_tree.nodes:
                if n.type == "TEX_IMAGE" and n.image:
                    images[n.name] = n.image.filepath
    if sc.world and sc.world.node_tree:
        for n in sc.world.node_tree.nodes:
            if n.type == "TEX_ENVIRONMENT" and n.image:
                images["environment"] = n.image.filepath
    return {"mm_per_unit": mpu * 1e3, "camera": camera, "lights": lights, "images": images}
