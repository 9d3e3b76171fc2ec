"""Texture-space diffusion: caching, inspection, material inputs and refusals."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from dermis.environment import equirect_directions, irradiance_sh_eval, sh_irradiance_from_equirect
from dermis.output import bloom
from dermis.renderer import Renderer
from dermis.scene.model import Texture
from dermis.verification import quad_scene


def test_camera_move_reuses_texture_space_passes(gl_ctx):
    sc = quad_scene(40.0, 40.0)
    with Renderer(sc, (48, 48), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        a = r.render("tsd")
        first = set(r.stats["passes_run"])
        assert {"shadow", "tsd_stretch", "tsd_irradiance", "tsd_blur", "tsd_final"} <= first
        sc.camera.position = (5.0, 3.0, 110.0)
        b = r.render("tsd")
        assert r.stats["passes_run"] == ["tsd_final"], r.stats["passes_run"]
        assert not np.allclose(a, b)  # the view did change
        sc.lights[0].intensity *= 2.0  # light changes re-run irradiance and blurs, not the stretch map
        c = r.render("tsd")
        ran = r.stats["passes_run"]
        assert "tsd_irradiance" in ran and "tsd_blur" in ran and "tsd_stretch" not in ran
        np.testing.assert_allclose(c[20:28, 20:28], 2 * b[20:28, 20:28], rtol=2e-3, atol=1e-5)


def test_roughness_map_changes_the_highlight(gl_ctx):
    sc = quad_scene(40.0, 40.0)
    sc.material.rho_s = 0.5
    sc.camera.position = (0.0, 0.0, 120.0)
    sc.lights[0].direction = (0.0, 0.0, -1.0)
    with Renderer(sc, (32, 32), irradiance_size=64, ctx=gl_ctx, samples=0) as r:
        spec_const = r.render("tsd", output_mode=2)[16, 16, 0]
        sc.material.roughness_map = Texture(np.full((4, 4, 1), 0.15, np.float32), "test:rough")
        spec_map = r.render("tsd", output_mode=2)[16, 16, 0]
    # peak of KSK at normal incidence ~ rho_s F0 / (4 m^2) / pi: scales as 1 / m^2
    assert spec_map / spec_const == pytest.approx((0.3 / 0.15) ** 2, rel=0.08)


def test_overlapping_uvs_are_refused_by_tsd_only_when_the_scene_asks_for_the_mesh_uvs(tmp_path):
    """texture_space_uv = "mesh" keeps the old refusal (one line, exit 2, no output); lambert
    renders regardless, and the default ("auto") renders tsd on a generated layout."""
    obj = tmp_path / "mirror.obj"
    obj.write_text(
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nv 2 -1 0\nv 4 -1 0\nv 4 1 0\nv 2 1 0\n"
        "vt 0.1 0.1\nvt 0.9 0.1\nvt 0.9 0.9\nvt 0.1 0.9\n"
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\nf 5/1 6/2 7/3\nf 5/1 7/3 8/4\n")
    toml = tmp_path / "mirror.toml"
    toml.write_text('[scene]\nmm_per_unit = 20.0\n[mesh]\nfile = "mirror.obj"\ntexture_space_uv = "mesh"\n'
                    '[[lights]]\ntype = "directional"\ndirection = [0.0, 0.0, -1.0]\n')
    out = tmp_path / "x.png"
    base = [sys.executable, "-m", "dermis.cli", "render"]
    opts = ["--size", "32x32", "--out", str(out)]
    res = subprocess.run(base + [str(toml)] + opts + ["--technique", "tsd"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    lines = [l for l in res.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and "overlaps" in lines[0] and "mirror.obj" in lines[0], res.stderr
    assert not out.exists() and not list(tmp_path.glob(".x.png*"))
    res = subprocess.run(base + [str(toml)] + opts + ["--technique", "lambert"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and out.exists(), res.stderr
    out.unlink()
    res = subprocess.run(base + [str(obj)] + opts + ["--technique", "tsd"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and out.exists(), res.stderr


def test_debug_buffers_and_stats_from_cli(tmp_path):
    import json

    import OpenEXR

    out, stats, dbg = tmp_path / "a.png", tmp_path / "s.json", tmp_path / "buffers"
    scene = tmp_path / "sphere.toml"
    scene.write_text('[scene]\nmm_per_unit = 30.0\n[mesh]\nbuiltin = "sphere"\n')
    res = subprocess.run([sys.executable, "-m", "dermis.cli", "render", str(scene), "--size", "64x64", "--out", str(out),
                          "--stats", str(stats), "--irradiance-size", "128", "--debug-buffers", str(dbg)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    s = json.loads(stats.read_text())
    assert s["technique"] == "tsd" and "tsd_blur" in s["passes_ms"] and "tsd_final" in s["passes_run"]
    names = {p.stem for p in dbg.glob("*.exr")}
    assert {"irradiance", "stretch", "blur_1", "blur_6", "translucency", "shadow_depth", "specular"} <= names
    with OpenEXR.File(str(dbg / "irradiance.exr")) as f:
        rgb = f.channels()["RGB"].pixels
    assert rgb.shape == (128, 128, 3) and np.isfinite(rgb).all() and rgb.max() > 0


def test_sh_irradiance_matches_brute_force_integration():
    """The environment's 9-coefficient irradiance against direct numerical integration of
    radiance x max(cos, 0) over the sphere, for a smooth HDR sky (order-2 SH is accurate to a few %
    for irradiance: Ramamoorthi & Hanrahan 2001 report < 3% average error)."""
    h, w = 32, 64
    d, dw = equirect_directions(h, w)
    sky = np.stack([1.0 + 0.8 * d[..., 1], 0.6 + 0.3 * d[..., 0], 0.4 + 0.2 * np.maximum(d[..., 2], 0)], -1)
    coeffs = sh_irradiance_from_equirect(sky)
    rng = np.random.default_rng(1)
    normals = rng.normal(size=(40, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    brute = np.einsum("nhw,hwc->nc", np.maximum(np.einsum("nk,hwk->nhw", normals, d), 0) * dw, sky)
    sh = irradiance_sh_eval(coeffs, normals)
    assert np.abs(sh / brute - 1).mean() < 0.03
    assert np.abs(sh / brute - 1).max() < 0.08


def test_bloom_conserves_energy_and_spreads():
    img = np.zeros((64, 64, 3), np.float32)
    img[32, 32] = 100.0
    out = bloom(img, 0.1, 0.05)
    assert out.sum() == pytest.approx(img.sum(), rel=1e-4)
    from scipy.special import erf

    s = 0.05 * 64  # the peak keeps 90% plus 10% of the Gaussian's mass in its own pixel
    own = erf(0.5 / (s * np.sqrt(2))) ** 2
    assert out[32, 32, 0] == pytest.approx(90.0 + 10.0 * own, rel=1e-3)
    assert out[32, 40, 0] > 0 and out[32, 32, 0] < 100.0
    np.testing.assert_array_equal(bloom(img, 0.0, 0.05), img)


def test_uv_on_triangle_is_the_closest_point_of_the_triangle(gl_ctx):
    """tsd/triangle_uv.glsl's uv_on_triangle (run in a compute shader) against brute force: for
    random UV triangles (some degenerate: corners in a line, or coincident) and points around them,
    the point returned lies on the triangle (barycentrics >= -1e-5) and is as close to the input as
    the closest of 40k points sampled over the triangle, within that sampling's spacing; a point
    inside a proper triangle comes back bit for bit."""
    from dermis.gl.shaders import load_shader_source

    rng = np.random.default_rng(12)
    n = 256
    tris = rng.uniform(0.2, 0.8, (n, 3, 2))
    tris[:32, 2] = tris[:32, 0] + 0.37 * (tris[:32, 1] - tris[:32, 0])  # corners in a line
    tris[32:40, 1] = tris[32:40, 2] = tris[32:40, 0]  # one point
    centre = tris.mean(axis=1)
    pts = centre + rng.normal(0.0, 0.12, (n, 2))
    w = rng.dirichlet(np.ones(3), 64)
    pts[40:104] = np.einsum("ij,ijk->ik", w, tris[40:104])  # inside proper triangles
    src = load_shader_source("tsd/triangle_uv.glsl", {"TRIANGLE_UV_BINDING": 0}) + """
layout(local_size_x = 64) in;
layout(std430, binding = 1) readonly buffer Points { vec2 points[]; };
layout(std430, binding = 2) writeonly buffer Result { vec2 result[]; };
void main() {
    int i = int(gl_GlobalInvocationID.x);
    result[i] = uv_on_triangle(points[i], i);
}
"""
    cs = gl_ctx.compute_shader(src)
    bufs = [gl_ctx.buffer(np.ascontiguousarray(a, np.float32).tobytes()) for a in (tris, pts, np.zeros((n, 2)))]
    try:
        for binding, b in enumerate(bufs):
            b.bind_to_storage_buffer(binding)
        cs.run(n // 64)
        q = np.frombuffer(bufs[2].read(), np.float32).reshape(n, 2).astype(np.float64)
    finally:
        for b in bufs:
            b.release()
        cs.release()
    t = tris.astype(np.float32).astype(np.float64)
    p = pts.astype(np.float32).astype(np.float64)
    # brute force: 200 x 200 barycentric grid over each triangle (spacing <= edge / 199)
    a, b = np.meshgrid(np.linspace(0, 1, 200), np.linspace(0, 1, 200))
    keep = a + b <= 1.0
    bary = np.stack([1.0 - a[keep] - b[keep], a[keep], b[keep]], 1)
    samples = np.einsum("sj,njk->nsk", bary, t)
    best = np.sqrt(((samples - p[:, None]) ** 2).sum(-1)).min(axis=1)
    got = np.linalg.norm(q - p, axis=1)
    edge = np.max(np.linalg.norm(t - np.roll(t, 1, axis=1), axis=2), axis=1)
    assert np.all(got <= best + 1e-6), np.max(got - best)
    assert np.all(got >= best - edge / 199.0 - 1e-6), np.min(got - best + edge / 199.0)
    # on the triangle: the barycentrics of q in the proper ones are >= 0 (the degenerate ones' are
    # ill-posed: their distance check above holds q to them)
    proper = np.arange(n) >= 40
    M = np.stack([t[proper, 1] - t[proper, 0], t[proper, 2] - t[proper, 0]], axis=2)
    l12 = np.linalg.solve(M, (q[proper] - t[proper, 0])[..., None])[..., 0]
    assert np.all(l12 >= -1e-5) and np.all(l12.sum(1) <= 1 + 1e-5)
    assert np.array_equal(q[40:104], p[40:104].astype(np.float32).astype(np.float64))


@pytest.mark.parametrize("extra_light", [False, True], ids=["3 lights, stored sharp shadows", "4 lights, per sample"])
def test_split_irradiance_equals_the_one_raster_and_keeps_its_inputs_while_only_the_lights_change(
        example_head_toml, gl_ctx, monkeypatch, extra_light):
    # tsd's irradiance pass in two parts (dermis.gl.irradiance_inputs; tsd.SPLIT_IRRADIANCE): the
    # light-independent inputs once per content, a full-screen pass adding the lights per lighting
    # change. Every output the one mesh raster gives (I_0 with the bounce, its dilation into the gutters,
    # the stored sharp shadows, rho E for the bounce) must be the raster's to float rounding on the head
    # (its maps, normal map, 3-4 shadowed lights, environment, seams); a light move must reuse the inputs,
    # a material change must redraw them, and either way the result is a fresh Renderer's to the bit.
    import dermis
    import dermis.techniques.tsd as tsd_module
    from dermis.scene.model import Light

    sc = dermis.load_scene(example_head_toml)
    if extra_light:
        sc.lights.append(Light(kind="directional", direction=(0.3, 0.8, -0.5), color=(1.0, 0.9, 0.8), intensity=0.8))
    keys = ["irradiance", "irradiance_dilated", ("bounce_exitant", 0)] + ([] if extra_light else ["sharp_shadow"])

    def textures(r):
        t = r.technique("tsd")

        def read(tex):  # the sharp shadows are RGBA8 (read_texture reads float targets)
            if tex.dtype == "f1":
                return np.frombuffer(tex.read(), np.uint8).reshape(tex.size[1], tex.size[0], 4) / 255.0
            return t.read_texture(tex).astype(np.float64)
        return {k: read(t.tex[k]) for k in keys}

    def fresh(split):
        monkeypatch.setattr(tsd_module, "SPLIT_IRRADIANCE", split)
        with Renderer(sc, (64, 64), irradiance_size=128, shadow_size=512, ctx=gl_ctx, samples=0) as f:
            img = f.render("tsd")
            return img, textures(f), list(f.stats["passes_run"])

    img_r, raster, ran_r = fresh(False)
    img_s, split, ran_s = fresh(True)
    assert "tsd_irradiance_inputs" in ran_s and "tsd_irradiance_inputs" not in ran_r
    for k in keys:
        a, b = raster[k], split[k]
        assert a.max() > 0.05, k  # something was drawn
        np.testing.assert_array_equal(a[..., 3] > 0, b[..., 3] > 0, err_msg=str(k))  # the same coverage
        np.testing.assert_allclose(b, a, rtol=0, atol=(1.5 / 255 if k == "sharp_shadow" else 1e-3 * a.max()), err_msg=str(k))
        # mean |difference| / max: I_0 ~1.3e-6 (float rounding of the same sums); rho E ~5.5e-5 (its
        # albedo^(1 - mix) input is 16-bit: tsd.INPUT_DTYPES)
        assert np.abs(b - a).mean() < (1e-4 if k == ("bounce_exitant", 0) else 1e-5) * a.max(), k
    np.testing.assert_allclose(img_s, img_r, rtol=0, atol=1e-3 * img_r.max())
    if extra_light:  # the inputs' invalidation does not depend on the light count: checked once
        return

    monkeypatch.setattr(tsd_module, "SPLIT_IRRADIANCE", True)
    with Renderer(sc, (64, 64), irradiance_size=128, shadow_size=512, ctx=gl_ctx, samples=0) as r:
        r.render("tsd")
        before = textures(r)["irradiance"]
        sc.lights[0].direction = (-0.55, -0.45, -0.70)  # the key light to the other side
        r.render("tsd")
        assert "tsd_irradiance" in r.stats["passes_run"]
        assert "tsd_irradiance_inputs" not in r.stats["passes_run"]
        moved = textures(r)
        assert np.abs(moved["irradiance"] - before).max() > 0.1 * before.max()  # the move shows
        for k, v in fresh(True)[1].items():
            np.testing.assert_array_equal(moved[k], v, err_msg=str(k))
        sc.material.mix = 0.7  # albedo^mix in I_0, albedo^(1 - mix) in rho E: both inputs
        r.render("tsd")
        assert "tsd_irradiance_inputs" in r.stats["passes_run"]
        recoloured = textures(r)
        assert np.abs(recoloured["irradiance"] - moved["irradiance"]).max() > 0.05 * before.max()
        for k, v in fresh(True)[1].items():
            np.testing.assert_array_equal(recoloured[k], v, err_msg=str(k))
