"""Assembling the procedural head: parts, normals, the xatlas UV layout, landmarks; the cached
``build_default_head``."""

from __future__ import annotations

import functools

import numpy as np

from dermis.geometry.atlas import atlas_on_welded_surface
from dermis.scene.procedural_head.ears import _build_ear, _ear_point
from dermis.scene.procedural_head.implicit import _Shape, _raycast
from dermis.scene.procedural_head.meshing import _build_head_surface, _vertex_normals
from dermis.scene.procedural_head.model import (ATLAS_PADDING_TEXELS, ATLAS_RESOLUTION, ATLAS_SEAMLESS_BOXES,
                                                MM_PER_UNIT, PARTS, PORE_SPACING_MM, ProceduralHead)
from dermis.scene.procedural_head.painter import _textures

@functools.lru_cache(maxsize=2)
def _geometry():
    """Mesh, packed UVs, islands and landmarks (independent of the texture size and seed)."""
    shape = _Shape()
    parts, ring = _build_head_surface(shape)
    Pf, Tf, Pb, Tb, ear = _build_ear(shape)
    mirror = np.array([-1.0, 1.0, 1.0])
    parts["left_ear_front"] = (Pf, Tf)
    parts["left_ear_back"] = (Pb, Tb)
    parts["right_ear_front"] = (Pf * mirror, Tf[:, ::-1].copy())
    parts["right_ear_back"] = (Pb * mirror, Tb[:, ::-1].copy())

    # assemble the parts (triangle labels kept: the texture painter's masks use them)
    Ps, Ts, isl = [], [], []
    base = 0
    for k, name in enumerate(PARTS):
        P, T = parts[name]
        Ps.append(P)
        Ts.append(T + base)
        isl.append(np.full(len(T), k, np.int8))
        base += len(P)
    P = np.concatenate(Ps)
    T = np.concatenate(Ts)
    island = np.concatenate(isl)
    # normals: smooth across part boundaries (vertices at the same position share a normal), but
    # the flat bottom cut keeps its own (sharp edge)
    key = np.round(P, 6)
    bottom = np.zeros(len(P), bool)
    b0 = sum(len(parts[n][0]) for n in PARTS[:2])
    bottom[b0 : b0 + len(parts["bottom_cap"][0])] = True
    key = np.concatenate([key, bottom[:, None].astype(float)], 1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    N = _vertex_normals(P, T, group.ravel())
    # UV layout: xatlas charts of the welded surface, packed with ATLAS_PADDING_TEXELS gutters at
    # ATLAS_RESOLUTION (dermis.geometry.atlas), none inside ATLAS_SEAMLESS_BOXES; vertices split along the seams
    vm, T, UV = atlas_on_welded_surface(P, T, ATLAS_RESOLUTION, ATLAS_PADDING_TEXELS, join_boxes=ATLAS_SEAMLESS_BOXES)
    P, N = P[vm], N[vm]
    T = T.astype(np.int64)
    UV = UV.astype(np.float64)

    # landmarks
    C = shape.C
    e = shape.EYE
    targets = {
        "crown": C + [0, 1, 0],
        "forehead": [0, 6.0, 9.0],
        "left_eye": [e[0], e[1], e[2] + shape.EYE_R],
        "right_eye": [-e[0], e[1], e[2] + shape.EYE_R],
        "left_eye_inner_socket": [1.75, 1.75, 8.0],
        "right_eye_inner_socket": [-1.75, 1.75, 8.0],
        "left_nostril": shape.NOSTRIL,
        "right_nostril": shape.NOSTRIL * mirror,
        "lips": [0, shape.STOMION_Y, 9.5],
        "upper_lip": [0, shape.STOMION_Y + 0.45, 9.5],
        "lower_lip": [0, shape.STOMION_Y - 0.5, 9.5],
        "left_cheek": [4.0, -1.2, 7.0],
        "right_cheek": [-4.0, -1.2, 7.0],
        "chin": [0, -8.4, 9.5],
        "neck": [0, -14.0, 5.0],
    }
    dirs = np.array([np.asarray(v, float) - C for v in targets.values()])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    th = _raycast(shape, C, dirs, iters=12, tol=1e-5)
    lm = {"head_centre": C.copy()}
    lm.update({k: C + t * d for k, t, d in zip(targets, th, dirs)})
    lm.update({
        "nose_tip": P[np.argmax(np.where((np.abs(P[:, 0]) < 1) & (P[:, 1] > -3) & (P[:, 1] < 0), P[:, 2], -np.inf))],
        "left_ear": _ear_point(ear, 2.2, 0.6),
        "right_ear": _ear_point(ear, 2.2, 0.6) * mirror,
        "left_ear_root": ear["root"].copy(),
        "right_ear_root": ear["root"] * mirror,
    })
    lm = {k: np.asarray(v, np.float32) for k, v in lm.items()}
    return dict(P=P, N=N, UV=UV, T=T, island=island, landmarks=lm, shape=shape, ear=ear)




def _readonly(a):
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=4)
def build_default_head(texture_size: int = 1024, seed: int = 7) -> ProceduralHead:
    """The built-in default scene's head-and-neck bust (see the module docstring).

    Deterministic for given arguments and cached: the returned arrays are read-only."""
    if int(texture_size) < 64:
        raise ValueError("texture_size must be at least 64")
    geo = _geometry()
    albedo, normal_map, specular, texel_mm = _textures(geo, int(texture_size), int(seed))
    return ProceduralHead(
        positions=_readonly(geo["P"].astype(np.float32)),
        normals=_readonly(geo["N"].astype(np.float32)),
        uvs=_readonly(geo["UV"].astype(np.float32)),
        indices=_readonly(geo["T"].astype(np.uint32)),
        albedo=_readonly(albedo),
        normal_map=_readonly(normal_map),
        specular=_readonly(specular),
        mm_per_unit=MM_PER_UNIT,
        pore_spacing_mm=PORE_SPACING_MM,
        landmarks={k: _readonly(v) for k, v in geo["landmarks"].items()},
        islands=_readonly(geo["island"]),
        texel_mm=texel_mm,
    )
