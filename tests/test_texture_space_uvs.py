"""Texture-space diffusion on a generated UV set (dermis.geometry.texture_space): meshes whose UVs
overlap or are missing render with tsd, the material keeps the asset's UVs, and the impulse and
seam checks hold on the generated layout."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import dermis
from dermis.errors import DermisError
from dermis.geometry.texture_space import corner_surface_metric, layout_problem, with_texture_space_uvs
from dermis.renderer import Renderer
from dermis.scene.builtin import cylinder_seam, uv_sphere
from dermis.scene.loaders import finish_mesh, load_mesh_file
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial, Texture
from dermis.verification import impulse_error_on_layout, seam_deviation

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_loaders import gltf_document, write_gltf  # noqa: E402

LUM = np.array([0.2126, 0.7152, 0.0722])


def _mirrored_sphere_mesh():
    p, n, uv, t = uv_sphere(radius=20.0, nu=48, nv=24)
    uv = uv.copy()
    uv[:, 0] = 1.0 - np.abs(2.0 * uv[:, 0] - 1.0)  # the two halves share one half of the image
    return p, n, uv, t


def _lit_scene(mesh, albedo=None):
    return Scene(mesh=mesh, material=SkinMaterial(albedo=albedo, albedo_color=(0.8, 0.6, 0.5), rho_s=0.0,
                                                  pore_strength=0.0),
                 lights=[Light(direction=(-0.3, -0.2, -1.0), intensity=np.pi)],
                 camera=Camera(position=(0.0, 0.0, 160.0), fov_deg=20.0),
                 environment=Environment(color=(0.05, 0.05, 0.05)), mm_per_unit=1.0)


def test_mirrored_uvs_render_with_tsd_and_the_albedo_keeps_the_mesh_uvs(gl_ctx):
    """A sphere whose two halves share UVs: 'auto' generates a texture-space set (unique), the
    vertices are split along its charts with every triangle's own UVs kept, and tsd's colours
    follow the albedo map through the asset's UVs as lambert's do (a quadrant-coloured map)."""
    p, n, uv, t = _mirrored_sphere_mesh()
    mesh = finish_mesh(p, n, uv, t, "test:mirrored-sphere", "v-up")
    assert "overlaps" in layout_problem(mesh.uvs, mesh.indices)
    img = np.zeros((64, 64, 3), np.float32)
    img[:32, :32] = (0.8, 0.1, 0.1)
    img[:32, 32:] = (0.1, 0.8, 0.1)
    img[32:, :32] = (0.1, 0.1, 0.8)
    img[32:, 32:] = (0.7, 0.7, 0.1)
    sc = _lit_scene(mesh, Texture(img, "test:quadrants"))
    with Renderer(sc, (64, 64), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        tsd = r.render("tsd")
        lam = r.render("lambert")
    g = sc.mesh
    assert g is not mesh and g.texture_space_uvs is not None
    assert layout_problem(g.texture_space_uvs, g.indices) is None
    np.testing.assert_array_equal(g.uvs[g.indices], mesh.uvs[mesh.indices])
    np.testing.assert_array_equal(g.positions[g.indices], mesh.positions[mesh.indices])
    lit = (lam @ LUM) > 0.3 * (lam @ LUM).max()
    assert lit.sum() > 300
    # chromaticity per pixel: tsd blurs light, not the map's colour boundaries' placement
    ct = tsd[lit] / tsd[lit].sum(1, keepdims=True)
    cl = lam[lit] / lam[lit].sum(1, keepdims=True)
    assert np.median(np.abs(ct - cl)) < 0.03
    assert np.corrcoef(ct[:, 0], cl[:, 0])[0, 1] > 0.9


def test_mesh_mode_keeps_refusing_an_overlapping_layout(gl_ctx):
    p, n, uv, t = _mirrored_sphere_mesh()
    mesh = finish_mesh(p, n, uv, t, "test:mirrored-sphere", "v-up")
    mesh.texture_space_uv = "mesh"
    with Renderer(_lit_scene(mesh), (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        with pytest.raises(DermisError, match="overlaps itself"):
            r.render("tsd")
    with pytest.raises(DermisError, match="texture_space_uv must be one of"):
        with_texture_space_uvs(mesh, "sometimes")


def test_obj_without_uvs_renders_with_tsd(tmp_path, gl_ctx):
    """An OBJ with no vt lines: the loader generates an xatlas layout; tsd renders it, lit."""
    p, n, uv, t = uv_sphere(radius=1.0, nu=24, nv=12)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in p] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in t]
    obj = tmp_path / "nouv.obj"
    obj.write_text("\n".join(lines) + "\n")
    mesh, _ = load_mesh_file(obj)
    assert layout_problem(mesh.uvs, mesh.indices) is None
    np.testing.assert_allclose(mesh.positions[mesh.indices], p[t], atol=1e-6)
    sc = _lit_scene(mesh)
    sc.mm_per_unit = 20.0
    sc.camera = Camera(position=(0.0, 0.0, 8.0), fov_deg=20.0)
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        img = r.render("tsd")
        lam = r.render("lambert")
    assert img[16, 16] @ LUM > 0.5 * (lam[16, 16] @ LUM) > 0


def test_gltf_with_overlapping_uvs_renders_with_tsd(tmp_path, gl_ctx):
    """A glTF whose UVs are mirrored (and a glTF with no TEXCOORD_0): both render with tsd, lit."""
    p, n, uv, t = _mirrored_sphere_mesh()
    doc, binary = gltf_document(p, uv, t, normals=n)
    path = write_gltf(tmp_path / "mirrored.gltf", doc, binary)
    doc2, binary2 = gltf_document(p, None, t, normals=n)
    path2 = write_gltf(tmp_path / "nouv.gltf", doc2, binary2)
    for f in (path, path2):
        mesh, _ = load_mesh_file(f)
        sc = _lit_scene(mesh)
        with Renderer(sc, (48, 48), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
            img = r.render("tsd")
            lam = r.render("lambert")
        c = img[24, 24] @ LUM
        assert c > 0.5 * (lam[24, 24] @ LUM) > 0, f


def test_scanned_head_keeps_its_own_uvs_and_a_folded_copy_renders(lee_perry_smith, gl_ctx):
    """The scan's layout is unique: 'auto' leaves it alone. Folding its UVs in half (u -> 0.5 +
    |u - 0.5|, a mirrored layout) makes 'auto' generate one; tsd renders the head with it, within
    a few percent of the unfolded head's mean (the albedo is sampled through the folded UVs, so
    the colours differ where the two halves of the map do)."""
    sc = dermis.load_scene(Path(__file__).resolve().parents[1] / "examples" / "lee-perry-smith.toml")
    assert layout_problem(sc.mesh.uvs, sc.mesh.indices) is None
    assert with_texture_space_uvs(sc.mesh) is sc.mesh
    with Renderer(sc, (64, 64), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        own = r.render("tsd")
    folded = sc.mesh.uvs.copy()
    folded[:, 0] = 0.5 + np.abs(folded[:, 0] - 0.5)
    sc.mesh = finish_mesh(sc.mesh.positions, sc.mesh.normals, folded, sc.mesh.indices, "test:folded-head", "v-up")
    assert "overlaps" in layout_problem(sc.mesh.uvs, sc.mesh.indices)
    with Renderer(sc, (64, 64), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        gen = r.render("tsd")
    assert sc.mesh.texture_space_uvs is not None
    assert abs((gen @ LUM).mean() / (own @ LUM).mean() - 1) < 0.1


def test_impulse_response_on_a_generated_layout(gl_ctx):
    """The impulse test on an xatlas layout of the flat quad: same closed form (the texel's side
    in mm measured on the layout), same 3% bound; measured ~0.15% (as on the quad's own UVs)."""
    err, h = impulse_error_on_layout(gl_ctx, 256, texture_space_uv="generate")
    assert 0.05 < h < 0.2
    assert np.all(err < 0.03), err
    own, h_own = impulse_error_on_layout(gl_ctx, 256, texture_space_uv="mesh")
    assert h_own == pytest.approx(0.1, rel=1e-3) and np.all(own < 0.03)


def _cylinder_scene(seam_angle, mode):
    p, n, uv, t = cylinder_seam(radius=10.0, height=30.0, nu=128, nv=16, seam_angle=seam_angle)
    mesh = finish_mesh(p, n, uv, t, "test:cylinder", "v-up")
    mesh.texture_space_uv = mode
    return Scene(mesh=mesh, material=SkinMaterial(albedo_color=(0.8, 0.6, 0.5), rho_s=0.0, pore_strength=0.0),
                 lights=[Light(direction=(0.0, 0.0, -1.0), intensity=np.pi, cast_shadows=True)],
                 camera=Camera(position=(0.0, 0.0, 150.0), fov_deg=14.0),
                 environment=Environment(color=(0.02, 0.02, 0.02)), mm_per_unit=1.0)


def test_seams_of_a_generated_layout(gl_ctx):
    """The cylinder with its own seam at the back and an xatlas layout, whose cuts cross the lit
    front: across every visible texture-space seam, tsd / lambert steps by < 4%. Light does not
    cross a seam, so the step grows with the irradiance gradient there: the cylinder's own seam
    placed 0.6 rad off the light measures ~1.3%, xatlas's cuts (up to ~1.2 rad) ~2-3%."""
    dev, n = seam_deviation(_cylinder_scene(np.pi, "generate"), 128, 256, gl_ctx)
    assert n > 50, "the generated layout should cut the lit front"
    assert dev < 0.04, dev
    dev_own, n_own = seam_deviation(_cylinder_scene(0.6, "mesh"), 128, 256, gl_ctx)
    assert n_own > 50 and dev_own < 0.02, dev_own


def test_scene_key_texture_space_uv(tmp_path):
    toml = tmp_path / "s.toml"
    toml.write_text('[mesh]\nbuiltin = "sphere"\ntexture_space_uv = "generate"\n')
    assert dermis.load_scene(toml).mesh.texture_space_uv == "generate"
    toml.write_text('[mesh]\nbuiltin = "sphere"\ntexture_space_uv = "always"\n')
    with pytest.raises(DermisError, match="texture_space_uv must be one of"):
        dermis.load_scene(toml)


def _fold(join: bool):
    """Two 12 x 12 mm faces meeting at a right-angled edge along z (face A: y = 0, x <= 0, normal +y;
    face B: x = 0, y <= 0, normal +x; flat normals: a vertex per face), laid out by xatlas, with
    ``join`` the two faces' charts joined (dermis.geometry.parameterize.join_charts)."""
    from dermis.geometry.atlas import atlas_on_welded_surface

    L, n = 12.0, 48
    s, z = np.meshgrid(np.linspace(0.0, L, n + 1), np.linspace(0.0, L, n // 2 + 1), indexing="ij")
    zero = np.zeros_like(s)
    faces = [(np.stack([-s, zero, z], -1), (0.0, 1.0, 0.0)), (np.stack([zero, -s, z], -1), (1.0, 0.0, 0.0))]
    P, N, T = [], [], []
    for grid, normal in faces:
        i, j = np.meshgrid(np.arange(n), np.arange(n // 2), indexing="ij")
        a = sum(len(p) for p in P) + i * (n // 2 + 1) + j
        b = a + n // 2 + 1  # the next row
        t = np.concatenate([np.stack([a, b, b + 1], -1), np.stack([a, b + 1, a + 1], -1)])
        P.append(grid.reshape(-1, 3))
        N.append(np.tile(normal, (len(P[-1]), 1)))
        T.append(t.reshape(-1, 3))
    P, N, T = np.concatenate(P), np.concatenate(N), np.concatenate(T)
    wrong = np.sum(np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]) * N[T[:, 0]], 1) < 0
    T[wrong] = T[wrong][:, ::-1]  # counter-clockwise seen from outside
    boxes = (((-L - 1.0, -L - 1.0, -1.0), (1.0, 1.0, L + 1.0)),) if join else ()
    vm, t, uv = atlas_on_welded_surface(P, T, 256, 4, cache=False, join_boxes=boxes)
    return P[vm], N[vm], uv, t


def test_light_crosses_a_fold_whose_charts_are_joined(gl_ctx):
    """Issue 12 (round 21, seam21): tsd's blurs stay within a chart, so light does not cross a UV seam.
    xatlas cuts a right-angled fold into two charts (asserted: the plain layout, which the procedural head
    had under its nose); joined, one face lit (N.L = 1) and the other edge-on (N.L = 0), the light scattered
    across the edge on the dark face must match the closed form along the unfolded surface (the geodesic
    distance is the unfolded one): I_k(t) = E_B + (E_A - E_B) Phi(-t / sigma_k) at t = 0.3-2 mm past the
    edge, for the Gaussians wide enough to reach (k3-k6, sigma 0.43-2.7 mm). Measured: within 2.1% of the
    closed form's mean (k6 0.932 / 0.952 of E_A); with the plain layout tsd gives 0-0.047 of E_A there
    (checked: this test fails with join_boxes=()). 2.4 s at load 2."""
    from scipy.special import ndtr

    from dermis.verification import texel_positions

    def uv_gap_at_edge(P, uv):
        """The largest distance in UV between two copies of one vertex on the edge (0: one chart there)."""
        edge = np.nonzero(np.hypot(P[:, 0], P[:, 1]) < 1e-6)[0]
        _, group = np.unique(np.round(P[edge, 2], 5), return_inverse=True)
        return max(np.ptp(uv[edge][group.ravel() == g], axis=0).max() for g in np.unique(group))

    P, _, uv, _ = _fold(False)
    assert uv_gap_at_edge(P, uv) > 0.05, "xatlas alone should cut the fold"
    P, N, uv, t = _fold(True)
    assert uv_gap_at_edge(P, uv) < 1e-6
    mesh = finish_mesh(P.astype(np.float32), N.astype(np.float32), uv, t, "test:fold", "v-up")
    mesh.texture_space_uv = "mesh"
    sc = Scene(mesh=mesh, material=SkinMaterial(albedo_color=(0.8, 0.6, 0.5), rho_s=0.0, pore_strength=0.0),
               lights=[Light(direction=(0.0, -1.0, 0.0), intensity=np.pi, cast_shadows=False)],
               camera=Camera(position=(40.0, 40.0, 60.0), target=(0.0, 0.0, 6.0), fov_deg=30.0),
               environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0)
    with Renderer(sc, (32, 32), irradiance_size=256, shadow_size=256, ctx=gl_ctx, samples=0) as r:
        r.render("tsd")
        db = r.technique("tsd").debug_buffers()
        S = r.irradiance_size
    pos, cov = texel_positions(mesh, S)
    across = np.where(pos[..., 1] > -1e-4, pos[..., 0], -pos[..., 1])  # mm along the unfolded surface, 0 at the edge
    I0 = db["irradiance"][..., 0]
    EA, EB = np.median(I0[cov & (across < -4.0)]), np.median(I0[cov & (across > 4.0)])
    assert EA > 1.0 and EB == pytest.approx(0.0, abs=1e-3 * EA)
    band = cov & (across > 0.3) & (across < 2.0) & (np.abs(pos[..., 2] - 6.0) < 3.0)  # 6 mm from the open sides
    rows, cols = np.nonzero(band)
    v = sc.profile.normalized().variances_mm2
    for k in range(2, len(v)):
        b = db[f"blur_{k + 1}"][..., 0]
        got = b[rows * b.shape[0] // S, cols * b.shape[1] // S].mean()
        ref = (EB + (EA - EB) * ndtr(-across[band] / np.sqrt(v[k]))).mean()
        assert got == pytest.approx(ref, rel=0.04), (k + 1, got, ref)


def _fold_charts(joined: bool):
    """The fold of _fold (face A: y = 0, x = -s; face B: x = 0, y = -s; s in [0, 12] mm, z in [0, 12] mm)
    with its own UVs, 60 mm across the image. Two charts cut along the edge s = 0: A's UVs
    (80 / 256 - s / 60, 0.1 + z / 60), B's (0.55 + z / 60, 160 / 256 + s / 60), rotated 90 degrees from
    A's, each seam side facing an empty gutter of > 12 mm (wider than the widest blur's reach);
    ``joined``: one chart, B unfolded beside A, (80 / 256 + s / 60, 0.1 + z / 60). The edge lies on a texel
    boundary of every level at 256^2 (80 and 160 texels): a texel holds its centre's side, so an edge
    between texel centres reads as the mid-point of the nearest centres either side (up to half a texel,
    0.12 mm, off the true edge: 28 % on k3 at 0.3-2 mm past a seam at u = 0.3, measured)."""
    L, n = 12.0, 48
    s, z = np.meshgrid(np.linspace(0.0, L, n + 1), np.linspace(0.0, L, n // 2 + 1), indexing="ij")
    zero = np.zeros_like(s)
    uv_b = np.stack([80 / 256 + s / 60.0, 0.1 + z / 60.0], -1) if joined else np.stack([0.55 + z / 60.0, 160 / 256 + s / 60.0], -1)
    faces = [(np.stack([-s, zero, z], -1), (0.0, 1.0, 0.0), np.stack([80 / 256 - s / 60.0, 0.1 + z / 60.0], -1)),
             (np.stack([zero, -s, z], -1), (1.0, 0.0, 0.0), uv_b)]
    P, N, UV, T = [], [], [], []
    for grid, normal, uv in faces:
        i, j = np.meshgrid(np.arange(n), np.arange(n // 2), indexing="ij")
        a = sum(len(p) for p in P) + i * (n // 2 + 1) + j
        b = a + n // 2 + 1
        T.append(np.concatenate([np.stack([a, b, b + 1], -1), np.stack([a, b + 1, a + 1], -1)]).reshape(-1, 3))
        P.append(grid.reshape(-1, 3))
        N.append(np.tile(normal, (len(P[-1]), 1)))
        UV.append(uv.reshape(-1, 2))
    return (np.concatenate(P).astype(np.float32), np.concatenate(N).astype(np.float32), np.concatenate(UV),
            np.concatenate(T))


def _bilinear(level, rows, cols, S):
    """Red of a blurred level (its colour and coverage, row 0 = top) read at the centres of the level-0
    texels (rows, cols) of S x S as tsd/gaussians.glsl reads it: bilinear on the premultiplied data,
    divided by the coverage."""
    from scipy.ndimage import map_coordinates

    h, w = level.shape[:2]
    y, x = (rows + 0.5) * h / S - 0.5, (cols + 0.5) * w / S - 0.5
    red, cov = (map_coordinates(c, [y, x], order=1, mode="nearest") for c in (level[..., 0] * level[..., 3], level[..., 3]))
    return red / cov


def test_light_crosses_a_uv_seam(gl_ctx):
    """Issue 12 (round 22, seams22): the fold cut into two charts along its edge by its own UVs (the
    charts rotated 90 degrees from each other in the image); face A lit (N.L = 1), face B edge-on (N.L = 0).
    tsd's seam fill (dermis.geometry.seams) gives each blur step the other chart's light beyond the seam,
    so on B, 0.3-2 mm from the edge, I_k (read as the final pass reads it) must match the same fold laid
    out as one chart within 3 % (k3-k6, sigma 0.43-2.7 mm), and the closed form along the unfolded
    surface, E_B + (E_A - E_B) Phi(-t / sigma_k), within 4 % (k3-k5; k6 runs at level 4, whose 3.75 mm
    texels the band lies within: both layouts read it 0.89 of the closed form). Without the fill
    (seams=false: main's blur) B gets 0 of E_A there. And the fill is a no-op on a layout without a
    seam: the one-chart fold's tsd image is the same with it on and off, to the bit."""
    from scipy.special import ndtr

    from dermis.geometry.seams import seam_sides

    S = 256
    v = None
    got, img = {}, {}
    for joined in (False, True):
        P, N, uv, t = _fold_charts(joined)
        assert len(seam_sides(P, t, uv, 1e-6)[0]) == (0 if joined else 2 * 24)  # 24 edge segments, a side per chart
        mesh = finish_mesh(P, N, uv, t, "test:fold-charts", "v-up")
        mesh.texture_space_uv = "mesh"
        sc = Scene(mesh=mesh, material=SkinMaterial(albedo_color=(0.8, 0.6, 0.5), rho_s=0.0, pore_strength=0.0),
                   lights=[Light(direction=(0.0, -1.0, 0.0), intensity=np.pi, cast_shadows=False)],
                   camera=Camera(position=(40.0, 40.0, 60.0), target=(0.0, 0.0, 6.0), fov_deg=30.0),
                   environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0)
        v = sc.profile.normalized().variances_mm2
        # B's texels 0.3-2 mm from the edge, 3-9 mm along it (rows from the top: v = 1 - (row + 0.5) / S)
        tex = (np.arange(S) + 0.5) / S
        if joined:
            cols = np.nonzero(((tex - 80 / 256) * 60 > 0.3) & ((tex - 80 / 256) * 60 < 2.0))[0]
            rows = np.nonzero(((1 - tex - 0.1) * 60 > 3.0) & ((1 - tex - 0.1) * 60 < 9.0))[0]
            across = (tex[cols] - 80 / 256) * 60
        else:
            rows = np.nonzero(((1 - tex - 160 / 256) * 60 > 0.3) & ((1 - tex - 160 / 256) * 60 < 2.0))[0]
            cols = np.nonzero(((tex - 0.55) * 60 > 3.0) & ((tex - 0.55) * 60 < 9.0))[0]
            across = (1 - tex[rows] - 160 / 256) * 60
        rr, cc = np.meshgrid(rows, cols, indexing="ij")
        with Renderer(sc, (32, 32), irradiance_size=S, shadow_size=256, ctx=gl_ctx, samples=0) as r:
            for seams in (True, False):
                r.technique("tsd", seams=seams)
                img[joined, seams] = r.render("tsd")
                db = r.technique("tsd").debug_buffers()
                got[joined, seams] = [_bilinear(db[f"blur_{k + 1}"], rr.ravel(), cc.ravel(), S).mean() for k in range(len(v))]
            I0 = db["irradiance"][..., 0]
        EA = I0.max()
        # the closed form over the same texels (the band's distances, each row or column alike)
        ref = [EA * ndtr(-across / np.sqrt(vk)).mean() for vk in v]
        got[joined, "ref"] = ref
    np.testing.assert_array_equal(img[True, True], img[True, False])
    res = [(k + 1, got[False, True][k] / got[True, True][k], got[False, True][k] / got[False, "ref"][k],
            got[False, False][k] / got[False, "ref"][k]) for k in range(2, len(v))]
    for k, vs_one_chart, vs_closed_form, without_fill in res:
        assert vs_one_chart == pytest.approx(1.0, abs=0.03), res
        assert k == 6 or vs_closed_form == pytest.approx(1.0, abs=0.04), res
        assert without_fill < 0.01, res  # main's blur: nothing crosses


def test_seam_fill_targets_unfold_the_neighbour_chart():
    """dermis.geometry.seams on the two-chart fold (_fold_charts): every gutter texel beside the seam
    maps to the point of the other chart at the same distance along the unfolded surface (closed form:
    B's gutter texel at (u, v), s = 60 (v - 160/256) mm < 0 and z = 60 (u - 0.55) mm, is A's point
    (80/256 + s / 60, 0.1 + z / 60); A's gutter texel at u > 80/256 is B's point at s = 60 (u - 80/256)),
    to float precision, and its distance from the seam; and a chart squeezed in UV (B scaled by 1/20: 12 mm in 2.6 texels; the
    scanned head's closed eyelids) gets no targets and gives none (its unfold would throw texels
    millimetres over the surface; checked: with MIN_DENSITY 0 it gets 166). 0.2-0.6 s."""
    from dermis.geometry.seams import fill_targets

    P, N, uv, t = _fold_charts(False)
    S = 256
    tex, tgt, dist = fill_targets(P, t, uv, S, {0: 12})[0]
    u, v = (tex[:, 0] + 0.5) / S, (tex[:, 1] + 0.5) / S  # the gutter texels' centres (row 0 = v 0)
    on_b = u > 0.5  # B's gutter lies below B (v < 160/256, u 0.55-0.75), A's right of A (u > 80/256, v 0.1-0.3)
    assert on_b.sum() > 200 and (~on_b).sum() > 200 and np.all(v[on_b] < 160 / 256) and np.all(u[~on_b] > 80 / 256)
    s, z = 60 * (v[on_b] - 160 / 256), 60 * (u[on_b] - 0.55)
    np.testing.assert_allclose(tgt[on_b], np.c_[80 / 256 + s / 60, 0.1 + z / 60], atol=1e-6)
    np.testing.assert_allclose(dist[on_b], -s, atol=0.25 * 60 / S)  # mm from the seam (the search's samples: 1/4 texel)
    s, z = 60 * (u[~on_b] - 80 / 256), 60 * (v[~on_b] - 0.1)
    np.testing.assert_allclose(tgt[~on_b], np.c_[0.55 + z / 60, 160 / 256 + s / 60], atol=1e-6)
    squeezed = uv.copy()
    b = np.arange(len(uv)) >= len(uv) // 2  # face B's vertices (the second half)
    squeezed[b] = (uv[b] - uv[b].min(0)) * 0.05 + 0.6
    tex = fill_targets(P, t, squeezed, S, {0: 12})[0][0]
    assert len(tex) == 0


def test_seam_fill_draws_each_steps_own_texels(gl_ctx):
    """dermis.gl.seam_fill (round 22, seamcost22): a step draws only the rectangles of 4 x 4 cells holding
    its own fill texels (those within its reach), all steps' rectangles in one buffer. On the two-chart
    fold at 256^2, against numpy: the rectangles cover exactly the cells of the texels within each reach
    (cell_rectangles merges runs; their union rasterised here), and one draw into a float texture of
    random values writes every texel within the reach with the renormalised bilinear taps of the input
    (the weights as stored, unorm8) to 1e-6 and leaves every other texel, fill texels beyond the reach
    included, bit-identical. Checked: fails with each step drawing half its texels' cells. ~0.3 s."""
    import moderngl

    from dermis.gl.seam_fill import TILE, SeamFill
    from dermis.geometry.seams import bilinear_taps, cached_fill_targets
    from dermis.geometry.texture_space import texture_space_uvs

    P, N, uv, t = _fold_charts(False)
    mesh = finish_mesh(P, N, uv, t, "test:fold-charts", "v-up")
    mesh.texture_space_uv = "mesh"
    S = 256
    fill = SeamFill(gl_ctx)
    try:
        assert fill.prepare("fold", mesh, S, {0: 12})
        texels, targets, dist = cached_fill_targets(mesh.positions, mesh.indices, texture_space_uvs(mesh), S, {0: 12})[0]
        base, w = bilinear_taps(texels, targets, S)
        keep = w.sum(1) > 0
        texels, base, w, dist = texels[keep], base[keep], w[keep], dist[keep]
        w = np.round(w * 255.0) / 255.0  # as the weights texture holds them
        w /= w.sum(1, keepdims=True)
        rng = np.random.default_rng(5)
        tex = gl_ctx.texture((S, S), 4, dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        fbo = gl_ctx.framebuffer(color_attachments=[tex])
        for reach in np.quantile(dist, [0.3, 1.0]):  # a narrow step's and the widest
            inside = dist <= np.float32(reach)  # the shader compares in float32 (uReach), as count() does
            assert 0 < fill.prepare_step(0, reach) == inside.sum()
            first, count = fill._steps[(0, float(reach))]
            quads = np.concatenate(fill._quads).reshape(-1, 6, 2)[first // 6:(first + count) // 6]
            lo = np.round((quads[:, 0] + 1) / 2 * S).astype(int)  # corners in texels (x, y)
            hi = np.round((quads[:, 2] + 1) / 2 * S).astype(int)
            drawn = np.zeros((S, S), int)
            for (x0, y0), (x1, y1) in zip(lo, hi):
                drawn[y0:y1, x0:x1] += 1
            want = np.zeros((S // TILE, S // TILE), bool)
            want[texels[inside, 1] // TILE, texels[inside, 0] // TILE] = True
            assert drawn.max() == 1  # no overlap
            np.testing.assert_array_equal(drawn.reshape(S // TILE, TILE, S // TILE, TILE).max((1, 3)) > 0, want)
            src = rng.random((S, S, 4)).astype(np.float32)
            tex.write(src.tobytes())
            fill.draw(tex, fbo, 0, reach)
            out = np.frombuffer(tex.read(), np.float32).reshape(S, S, 4)
            ref = src.copy()
            b, ww, tx = base[inside], w[inside], texels[inside]
            ref[tx[:, 1], tx[:, 0]] = sum(ww[:, i, None] * src[np.minimum(b[:, 1] + dy, S - 1), np.minimum(b[:, 0] + dx, S - 1)]
                                          for i, (dx, dy) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))))
            np.testing.assert_allclose(out, ref, atol=1e-6, rtol=0)
            changed = np.zeros((S, S), bool)
            changed[tx[:, 1], tx[:, 0]] = True
            np.testing.assert_array_equal(out[~changed], src[~changed])
        fbo.release()
        tex.release()
    finally:
        fill.release()


def test_corner_surface_metric_is_the_first_fundamental_form():
    """corner_surface_metric (tsd's detail density, tsd/final.frag): for a layout that maps the surface
    affinely, P = A (u, v) + b, every corner holds A^T A (E, F, G) exactly, whatever the triangles;
    a corner of a chart's border is not averaged with the same point on another chart (the seam); a
    vertex averages its triangles' metrics weighted by their surface area."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 2)) * np.array([[20.0], [5.0], [9.0]])
    uv = rng.random((40, 2))
    from scipy.spatial import Delaunay

    t = Delaunay(uv).simplices
    p = uv @ A.T + np.array([1.0, -2.0, 0.5])
    m = corner_surface_metric(p, uv, t)
    G = A.T @ A
    assert m.shape == (len(t), 3, 4) and np.all(m[..., 3] == 0)
    np.testing.assert_allclose(m[..., :3].reshape(-1, 3), np.broadcast_to([G[0, 0], G[0, 1], G[1, 1]], (3 * len(t), 3)),
                               rtol=1e-5)
    # two triangles on a shared edge (0-1), the second twice as long along v: their shared vertices
    # average (1, 0, 1) and (1, 0, 4) by surface area 1 : 2
    p2 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -2, 0]], float)
    uv2 = np.array([[0, 0], [1, 0], [0, 1], [0, -1]], float)
    t2 = np.array([[0, 1, 2], [0, 3, 1]])
    m2 = corner_surface_metric(p2, uv2, t2)
    np.testing.assert_allclose(m2[0, 0, :3], [1.0, 0.0, 3.0], rtol=1e-6)  # (1 x 1 + 4 x 2) / 3 = 3
    np.testing.assert_allclose(m2[0, 2, :3], [1.0, 0.0, 1.0], rtol=1e-6)  # only the first triangle
    np.testing.assert_allclose(m2[1, 1, :3], [1.0, 0.0, 4.0], rtol=1e-6)
    # the same edge on two charts (vertex 1 and 3 split in uv): each side keeps its own metric
    p3 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -2, 0], [0, 0, 0], [1, 0, 0]], float)
    uv3 = np.array([[0, 0], [1, 0], [0, 1], [0.5, -1], [0.5, 0], [1.5, 0]], float)
    m3 = corner_surface_metric(p3, uv3, np.array([[0, 1, 2], [4, 3, 5]]))
    np.testing.assert_allclose(m3[0, :, :3], np.broadcast_to([1.0, 0.0, 1.0], (3, 3)), rtol=1e-6)
    np.testing.assert_allclose(m3[1, :, :3], np.broadcast_to([1.0, 0.0, 4.0], (3, 3)), rtol=1e-6)
