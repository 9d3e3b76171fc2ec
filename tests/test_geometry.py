"""The geometry package: Embree ray casting (hits, skips, ambient occlusion against a closed-form
form factor), the UV rasteriser and overlap test, xatlas atlases and their disk cache."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dermis.geometry.atlas import generate_atlas
from dermis.geometry.rasterize import overlap_fraction, rasterize_uv
from dermis.geometry.raycast import RayCaster
from dermis.scene.builtin import plane_xy, uv_sphere


def _square(half, z):
    p = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], float)
    return p, np.array([[0, 1, 2], [0, 2, 3]])


def test_occluded_skips_the_triangle_a_ray_leaves():
    p, t = _square(1.0, 0.0)
    rc = RayCaster(p, t)
    o = np.array([[0.3, -0.2, -1e-3]])  # just below triangle 0, going up through it
    d = np.array([[0.0, 0.0, 1.0]])
    assert rc.occluded(o, d)[0]
    assert not rc.occluded(o, d, skip=[0])[0]
    assert rc.occluded(o, d, skip=[1])[0]
    assert not rc.occluded(o, d, 0.0, 0.5e-3)[0]  # tmax before the plane
    t_hit, tri, bary = rc.closest_hit(o, d)
    assert tri[0] == 0 and t_hit[0] == pytest.approx(1e-3, rel=1e-9)
    # barycentrics of vertices 1 and 2 reproduce the hit point
    hp = p[0] + bary[0, 0] * (p[1] - p[0]) + bary[0, 1] * (p[2] - p[0])
    np.testing.assert_allclose(hp, [0.3, -0.2, 0.0], atol=1e-6)


def test_ambient_occlusion_under_a_square_equals_the_form_factor():
    """A point on the floor under a parallel square of half-width a at height h: the open
    cosine-weighted fraction is 1 - F, F = 4 F_corner(a/h, a/h) with the differential-area-to-
    rectangle form factor F_corner(X, Y) = 1/(2 pi) [X/sqrt(1+X^2) atan(Y/sqrt(1+X^2)) +
    Y/sqrt(1+Y^2) atan(X/sqrt(1+Y^2))] (Howell, A Catalog of Radiation Heat Transfer Configuration
    Factors, B-3)."""
    a = h = 1.0
    p, t = _square(a, h)
    rc = RayCaster(p, t)
    X = Y = a / h
    fc = (X / math.sqrt(1 + X * X) * math.atan(Y / math.sqrt(1 + X * X))
          + Y / math.sqrt(1 + Y * Y) * math.atan(X / math.sqrt(1 + Y * Y))) / (2 * math.pi)
    expected = 1.0 - 4.0 * fc  # 0.446
    ao, bent = rc.ambient_occlusion(np.zeros((4, 3)), np.tile([0.0, 0.0, 1.0], (4, 1)), 4096, seed=2)
    assert ao == pytest.approx(np.full(4, expected), abs=0.03)  # MC std ~0.008
    assert np.abs(bent[:, :2]).max() < 0.1  # symmetric: the bent normal is the normal
    _, bent_edge = rc.ambient_occlusion([[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]], 2048)
    assert bent_edge[0, 0] > 0.2 and abs(bent_edge[0, 1]) < 0.1  # under the edge: leans out (+x)
    ao_open, bent_open = rc.ambient_occlusion([[5.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]], 2048, max_distance=0.5)
    assert ao_open[0] == 1.0 and bent_open[0, 2] > 0.98  # limited reach: the square is too far


def test_hit_distances_inside_a_sphere_equal_its_radius():
    p, n, uv, t = uv_sphere(radius=2.0, nu=64, nv=32)
    rc = RayCaster(p, t)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dist = rc.hit_distances(np.zeros((500, 3)), d)
    # the tessellated sphere lies between its inscribed and circumscribed radii
    assert np.all(dist <= 2.0 + 1e-9) and np.all(dist > 2.0 * math.cos(math.pi / 32) ** 2)


def test_rasterizer_covers_each_triangle_area():
    """Texel counts equal UV area * texels (within the edge), the whole [0, 1] grid exactly once."""
    p, n, uv, t = plane_xy(size=2.0, n=6)
    R = 200
    tri, bary, cnt = rasterize_uv(uv, t, R, R, count=True)
    assert (tri >= 0).all() and cnt.min() >= 1
    assert overlap_fraction(uv, t, 256) == 0.0
    np.testing.assert_allclose(bary.sum(2), 1.0, atol=1e-5)
    one = rasterize_uv(uv, t[:1], R, R)[0]
    uva = uv[t[0]]
    e1, e2 = uva[1] - uva[0], uva[2] - uva[0]
    area = 0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0])
    assert (one == 0).sum() == pytest.approx(area * R * R, rel=0.05)


def test_overlap_fraction_of_a_mirrored_layout():
    p, n, uv, t = uv_sphere(radius=1.0, nu=48, nv=24)
    mirrored = uv.copy()
    mirrored[:, 0] = 1.0 - np.abs(2.0 * uv[:, 0] - 1.0)  # both halves on one
    assert overlap_fraction(uv, t) < 0.01
    assert overlap_fraction(mirrored, t) > 0.9


def test_xatlas_atlas_is_unique_padded_and_cached(tmp_path, monkeypatch):
    monkeypatch.setenv("DERMIS_CACHE_DIR", str(tmp_path))
    p, n, uv, t = uv_sphere(radius=1.0, nu=32, nv=16)
    a = generate_atlas(p, t, resolution=256, padding_px=4)
    assert not a.cached and 0.3 < a.utilization <= 1.0
    # same triangles on copies of the same vertices
    np.testing.assert_array_equal(p[a.vmapping][a.indices], p[t])
    assert a.uvs.min() >= 0.0 and a.uvs.max() <= 1.0
    assert overlap_fraction(a.uvs, a.indices, 512) == 0.0
    # charts = connected components of the atlas's triangles; their texels stay >= padding apart
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([a.indices[:, [0, 1]], a.indices[:, [1, 2]]]).astype(np.int64)
    nv = len(a.uvs)
    _, comp = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(nv, nv)), directed=False)
    chart = comp[a.indices[:, 0]]
    tri, _ = rasterize_uv(a.uvs, a.indices, 256, 256)
    ids = np.where(tri >= 0, chart[np.maximum(tri, 0)], -1)
    gaps = []
    for c in np.unique(ids[ids >= 0]):
        dist = ndimage.distance_transform_edt(ids != c)
        others = (ids >= 0) & (ids != c)
        if others.any():
            gaps.append(dist[others].min())
    assert len(gaps) > 1 and min(gaps) >= 4, min(gaps)
    # the disk cache returns the same atlas; another mesh is not served from it
    b = generate_atlas(p, t, resolution=256, padding_px=4)
    assert b.cached
    np.testing.assert_array_equal(a.uvs, b.uvs)
    np.testing.assert_array_equal(a.indices, b.indices)
    p2 = p * 1.5
    assert not generate_atlas(p2, t, resolution=256, padding_px=4).cached


def test_lscm_and_arap_flatten_a_developable_patch_isometrically():
    """dermis.geometry.parameterize (seam21): a half cylinder (radius 5, 3 units long, 40 x 12 quads) unrolls
    without distortion, so LSCM's map must be the 3-D edge lengths (the independent reference) times one
    scale (its pins are the chord's ends: 0.64 here; measured spread 1e-10), and ARAP's must be the lengths
    themselves (measured 4e-12 off; LSCM alone 0.36 off). No flipped triangle. ~0.2 s."""
    from dermis.geometry.parameterize import arap, lscm

    a, h = np.meshgrid(np.linspace(0.0, np.pi, 41), np.linspace(0.0, 3.0, 13), indexing="ij")
    P = np.stack([5 * np.cos(a), 5 * np.sin(a), h], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(40), np.arange(12), indexing="ij")
    q = (i * 13 + j).ravel()
    F = np.concatenate([np.stack([q, q + 13, q + 14], 1), np.stack([q, q + 14, q + 1], 1)])
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    L3 = np.linalg.norm(P[edges[:, 0]] - P[edges[:, 1]], axis=1)
    U0 = lscm(P, F)
    L0 = np.linalg.norm(U0[edges[:, 0]] - U0[edges[:, 1]], axis=1)
    assert np.ptp(L0 / L3) / np.mean(L0 / L3) < 1e-6
    U = arap(P, F, U0, 20)
    L2 = np.linalg.norm(U[edges[:, 0]] - U[edges[:, 1]], axis=1)
    assert np.max(np.abs(L2 / L3 - 1)) < 1e-6, np.max(np.abs(L2 / L3 - 1))
    d = U[F]
    signed = (d[:, 1, 0] - d[:, 0, 0]) * (d[:, 2, 1] - d[:, 0, 1]) - (d[:, 2, 0] - d[:, 0, 0]) * (d[:, 1, 1] - d[:, 0, 1])
    assert np.all(signed > 0) or np.all(signed < 0)


def test_bake_cache_store_writes_whole_files_and_swallows_unwritable_folders(tmp_path):
    # every disk cache (atlases, visibility, interreflection) writes through bake_cache.store: a temporary
    # name of its own, then renamed (dermis.fileio.atomic_write), so nothing half-written is ever read
    from dermis.geometry import bake_cache

    a = {"x": np.arange(5.0), "y": np.eye(2, dtype=np.float32)}
    bake_cache.store(tmp_path / "k.npz", a)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.npz"]  # no temporary left behind
    with np.load(tmp_path / "k.npz") as z:
        np.testing.assert_array_equal(z["x"], a["x"])
        np.testing.assert_array_equal(z["y"], a["y"])
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    bake_cache.store(blocker / "sub" / "k.npz", a)  # cannot be written: only costs the re-bake, no error
    assert blocker.read_text() == "not a folder"
