"""Cache invalidation: every product the Renderer keeps between frames is rebuilt when an input
it declares in dermis.invalidation.PRODUCTS changes (by value, by swap, or edited in place), and
only then; an identical fresh Renderer is the reference each time."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.errors import DermisError
from dermis.invalidation import PRODUCTS, fingerprint, product_keys, scene_inputs
from dermis.renderer import Renderer
from dermis.scene.builtin import uv_sphere
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial, Texture

SIZE = (32, 32)


def _sphere_mesh(radius=1.0):
    p, n, uv, t = uv_sphere(radius, 48, 24)
    return finish_mesh(p, n, uv, t, "test:sphere", "v-up")


def _scene():
    rng = np.random.default_rng(7)
    albedo = (0.3 + 0.4 * rng.random((16, 16, 3))).astype(np.float32)
    env = (0.05 + 0.1 * rng.random((8, 16, 3))).astype(np.float32)
    return Scene(mesh=_sphere_mesh(), material=SkinMaterial(albedo=Texture(albedo, "test:albedo"), pore_strength=0.0),
                 lights=[Light(direction=(0.4, -0.5, -0.75), intensity=3.0)],
                 camera=Camera(position=(0.3, 0.4, 4.0), fov_deg=35.0),
                 environment=Environment(image=Texture(env, "test:env")), mm_per_unit=20.0, technique="lambert")


def _fresh(scene, technique, gl_ctx, **kw):
    with Renderer(scene, SIZE, ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=256) as r:
        return r.render(technique, **kw)


def _renderer(scene, gl_ctx):
    return Renderer(scene, SIZE, ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=256)


# ---------------------------------------------------------------------- keys (no GL)
def test_fingerprint_sees_in_place_edits_and_ignores_identity():
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    k = fingerprint(a)
    assert fingerprint(a.copy()) == k  # equal content, another object: the same key
    a[1, 2] += 1.0
    assert fingerprint(a) != k  # the same object edited in place: a new key
    assert fingerprint(a[:, ::2]) != fingerprint(a[:, 1::2])  # non-contiguous views are read by value
    assert fingerprint(None) is None


def test_fingerprint_of_a_read_only_array_sees_an_edit_made_while_it_was_writable():
    a = np.zeros((4, 4), np.float32)
    a.flags.writeable = False
    k = fingerprint(a)
    assert fingerprint(a) == k
    a.flags.writeable = True  # edited between two frames, read-only again before the next
    a[0, 0] = 1.0
    a.flags.writeable = False
    assert fingerprint(a) != k


def test_fingerprint_of_an_immutable_array_is_remembered_and_an_edit_needs_a_new_array(monkeypatch):
    """A map stored in an immutable bytes object (as the loaders store decoded maps) is hashed once:
    numpy refuses to make it writable, so an edit must make a new array, which gets a new key."""
    import dermis.invalidation as inv

    a = inv.immutable(np.arange(64, dtype=np.float32).reshape(8, 8))
    k = fingerprint(a)
    with pytest.raises(ValueError):
        a.flags.writeable = True
    with pytest.raises(ValueError):
        a[0, 0] = 5.0
    calls = []
    real = inv.xxhash.xxh3_128_hexdigest
    monkeypatch.setattr(inv.xxhash, "xxh3_128_hexdigest", lambda b: calls.append(1) or real(b))
    assert fingerprint(a) == k and fingerprint(a[:, :4]) != k and not calls  # remembered: no pass over the bytes
    b = a.copy()
    b[0, 0] = 5.0
    assert fingerprint(b) != k and fingerprint(inv.immutable(b)) == fingerprint(b)
    # a writable array is hashed every time (an in-place edit must be seen)
    calls.clear()
    w = np.arange(64, dtype=np.float32)
    fingerprint(w), fingerprint(w)
    assert len(calls) == 2
    # two arrays over different parts of one bytes object are not confused
    buf = np.arange(32, dtype=np.float32).tobytes()
    lo, hi = np.frombuffer(buf, np.float32, 16), np.frombuffer(buf, np.float32, 16, offset=64)
    assert fingerprint(lo) != fingerprint(hi)
    assert fingerprint(lo) == fingerprint(np.arange(16, dtype=np.float32))


def test_loaded_scene_maps_are_immutable_and_keyed_once(monkeypatch):
    from pathlib import Path

    import dermis
    import dermis.invalidation as inv

    toml = Path(__file__).resolve().parents[1] / "examples" / "lee-perry-smith.toml"
    sc = dermis.load_scene(toml)
    assert not sc.material.albedo.data.flags.writeable
    k1 = product_keys(scene_inputs(sc, irradiance_size=64, epoch=0))
    hashed = []
    real = inv.xxhash.xxh3_128_hexdigest
    monkeypatch.setattr(inv.xxhash, "xxh3_128_hexdigest", lambda b: hashed.append(len(b)) or real(b))
    k2 = product_keys(scene_inputs(sc, irradiance_size=64, epoch=0))
    assert k1 == k2
    maps = [t.data.base.nbytes if t.data.base is not None else t.data.nbytes
            for t in (sc.material.albedo, sc.material.normal_map, sc.material.specular_map)]
    assert not set(hashed) & set(maps), "the maps were hashed again"
    sc.material.albedo = type(sc.material.albedo)(sc.material.albedo.data * 0.5, "edited")  # the way to edit it
    assert product_keys(scene_inputs(sc, irradiance_size=64, epoch=0))["material_textures"] != k1["material_textures"]


def test_every_product_declares_inputs_that_exist_and_changes_only_with_them():
    sc = _scene()
    inputs = scene_inputs(sc, irradiance_size=64, epoch=0)
    for product, names in PRODUCTS.items():
        assert names and set(names) <= set(inputs), product
    before = product_keys(inputs)
    sc.lights[0].intensity = 5.0  # lights, not their geometry
    after = product_keys(scene_inputs(sc, irradiance_size=64, epoch=0))
    changed = {p for p in PRODUCTS if before[p] != after[p]}
    assert changed == {p for p, names in PRODUCTS.items() if "lights" in names}
    assert "shadow_atlas" not in changed and "gpu_mesh" not in changed


# ---------------------------------------------------------------------- products (GL)
def test_in_place_albedo_edit_re_uploads_the_material(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        first = r.render("lambert")
        tex = r.gpu.textures["albedo"]
        r.render("lambert")
        assert r.gpu.textures["albedo"] is tex  # unchanged: not uploaded again
        sc.material.albedo.data[:] *= 0.5  # in place: same array object, same id
        edited = r.render("lambert")
        assert r.gpu.textures["albedo"] is not tex
    assert np.abs(edited - first).max() > 0.01
    np.testing.assert_allclose(edited, _fresh(sc, "lambert", gl_ctx), atol=1e-6)


def test_in_place_environment_edit_re_projects_its_sh(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        first = r.render("lambert")
        sc.environment.image.data[:] *= 4.0
        edited = r.render("lambert")
    assert np.abs(edited - first).max() > 1e-3
    np.testing.assert_allclose(edited, _fresh(sc, "lambert", gl_ctx), atol=1e-6)


def test_swapping_the_mesh_rebuilds_the_gpu_mesh_and_the_shadows(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        first = r.render("lambert")
        gpu = r.gpu
        sc.mesh = _sphere_mesh(0.6)
        swapped = r.render("lambert")
        assert r.gpu is not gpu and "shadow" in r.stats["passes_run"]
    assert np.abs(swapped - first).max() > 0.01
    np.testing.assert_allclose(swapped, _fresh(sc, "lambert", gl_ctx), atol=1e-6)


def test_in_place_mesh_edit_is_seen(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        first = r.render("lambert")
        sc.mesh.positions[:] *= 0.6
        edited = r.render("lambert")
        assert "shadow" in r.stats["passes_run"]
    assert np.abs(edited - first).max() > 0.01
    np.testing.assert_allclose(edited, _fresh(sc, "lambert", gl_ctx), atol=1e-6)


def test_texture_space_passes_re_run_only_when_their_inputs_change(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        r.render("tsd")
        r.render("tsd")
        assert r.stats["passes_run"] == ["tsd_final"]
        sc.camera.position = (0.5, 0.4, 4.0)  # the view is no input of texture space
        r.render("tsd")
        assert r.stats["passes_run"] == ["tsd_final"]
        sc.material.albedo.data[:4] *= 0.5  # in place
        edited = r.render("tsd")
        assert "tsd_irradiance" in r.stats["passes_run"] and "shadow" not in r.stats["passes_run"]
        r.technique("tsd", translucency_strength=0.5)  # an option: re-runs texture space too
        r.render("tsd")
        assert "tsd_irradiance" in r.stats["passes_run"]
        r.technique("tsd", translucency_strength=1.0)
        again = r.render("tsd")
    np.testing.assert_allclose(again, edited, atol=1e-6)
    np.testing.assert_allclose(edited, _fresh(sc, "tsd", gl_ctx), atol=1e-5)


def test_preintegrated_tables_follow_an_in_place_profile_edit(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        r.render("preintegrated")
        r.render("preintegrated")
        assert "preintegrated_tables" not in r.stats["passes_run"]
        sc.profile.variances_mm2[-1] *= 2.0
        edited = r.render("preintegrated")
        assert "preintegrated_tables" in r.stats["passes_run"]
    np.testing.assert_allclose(edited, _fresh(sc, "preintegrated", gl_ctx), atol=1e-5)


def test_invalidate_re_runs_shadows_and_texture_space(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        r.render("tsd")
        r.invalidate()
        r.render("tsd")
        assert {"shadow", "tsd_irradiance", "tsd_blur"} <= set(r.stats["passes_run"])
        assert "tsd_stretch" not in r.stats["passes_run"]  # once per mesh


def test_debug_buffers_leave_stats_and_last_frame_alone(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        img = r.render("preintegrated")
        stats, frame = dict(r.stats), r.last_frame
        bufs = r.debug_buffers("preintegrated")
        assert {"specular", "curvature_per_mm"} <= set(bufs)
        assert r.stats == stats and r.last_frame is frame
        # the specular side render is the same frame's specular term
        np.testing.assert_allclose(bufs["specular"], r.render("preintegrated", output_mode=2), atol=1e-6)
        np.testing.assert_allclose(r.render("preintegrated"), img, atol=1e-6)


# ---------------------------------------------------------------------- technique options
def test_technique_options_are_validated(gl_ctx):
    sc = _scene()
    with _renderer(sc, gl_ctx) as r:
        tsd = r.technique("tsd", multires=False, max_taps=8)
        assert tsd.options.multires is False and tsd.options.max_taps == 8
        with pytest.raises(DermisError, match="max_taps"):
            r.technique("tsd", max_taps=0)
        with pytest.raises(DermisError, match="unknown option colour"):
            r.technique("tsd", colour=1)
        with pytest.raises(DermisError, match="curvature_source"):
            r.technique("preintegrated", curvature_source="sideways")
        with pytest.raises(DermisError, match="translucency_strength"):
            r.technique("ssss", translucency_strength=float("nan"))
        assert tsd.options.max_taps == 8  # a refused change leaves the options as they were
        with pytest.raises(DermisError, match="Renderer.technique"):
            tsd.multires = True  # assignment would skip validation
        with pytest.raises(DermisError, match="output_mode"):
            r.render("tsd", output_mode=7)


def test_changing_the_scale_keeps_the_depth_only_shadow_map_and_matches_a_fresh_render(gl_ctx):
    """The atlas holds light-space depth only (no mm since the translucent shadow map went): a new
    mm_per_unit re-bakes the thickness and stretch, not the shadows, and the image is a fresh one's."""
    from dermis.verification import backlit_slab_scene

    sc = backlit_slab_scene(2.0, n=8)
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as r:
        r.render("tsd", output_mode=1)
        sc.mm_per_unit = 0.5
        a = r.render("tsd", output_mode=1)
        assert "shadow" not in r.stats["passes_run"] and "thickness" in r.stats["passes_run"]
    with Renderer(sc, (32, 32), irradiance_size=128, ctx=gl_ctx, samples=0) as fresh:
        b = fresh.render("tsd", output_mode=1)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)
