"""Per-frame overhead (issue 14): what a frame no longer recomputes is still recomputed the moment
its inputs change. Each cache added to cut the per-frame Python (values derived from the mesh's
content, uniform values a program already holds, the blur chain's plan, the product keys) is
checked against a fresh computation after an in-place edit, a swap and a plain value change;
frames are compared with a fresh Renderer's. Timings: benchmarks/frame_overhead.py, never here."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dermis.camera import cross3
from dermis.errors import DermisError
from dermis.framing import fit_camera, framed_camera, head_vertices
from dermis.invalidation import memo_by_content
from dermis.renderer import Renderer
from dermis.scene.builtin import uv_sphere
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial, Texture


def _scene():
    """A sphere and a small one between it and light 0, so that light 0 casts a shadow whose
    penumbra (shadow softness) shows; each sphere on its own half of the UV square."""
    p, n, uv, t = uv_sphere(1.0, 48, 24)
    q, m, uv2, t2 = uv_sphere(0.3, 16, 8)
    d = -np.array([0.4, -0.5, -0.75]) / np.linalg.norm([0.4, -0.5, -0.75])
    p, n, t = np.concatenate([p, q + 1.6 * d]), np.concatenate([n, m]), np.concatenate([t, t2 + len(p)])
    uv = np.concatenate([uv * (0.5, 1.0), uv2 * (0.5, 1.0) + (0.5, 0.0)])
    rng = np.random.default_rng(3)
    albedo = (0.3 + 0.4 * rng.random((16, 16, 3))).astype(np.float32)
    return Scene(mesh=finish_mesh(p, n, uv, t, "test:sphere", "v-up"),
                 material=SkinMaterial(albedo=Texture(albedo, "test:albedo"), pore_strength=0.0),
                 lights=[Light(direction=(0.4, -0.5, -0.75), intensity=3.0),
                         Light(direction=(-0.6, -0.2, -0.5), intensity=1.0, color=(0.7, 0.8, 1.0))],
                 camera=Camera(position=(0.3, 0.4, 4.0), fov_deg=35.0, fit=True),
                 environment=Environment(color=(0.05, 0.05, 0.06)), mm_per_unit=20.0, technique="tsd")


def _fresh(scene, technique, gl_ctx):
    with Renderer(scene, (32, 32), ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=256) as r:
        return r.render(technique)


def test_cross3_is_numpys_cross_bit_for_bit():
    rng = np.random.default_rng(0)
    for _ in range(2000):
        a, b = rng.normal(size=3) * 10.0 ** rng.integers(-6, 6), rng.normal(size=3)
        assert np.array_equal(cross3(a, b), np.cross(a, b))


def test_memo_by_content_follows_in_place_edits_and_never_hands_out_its_values():
    p = np.arange(30, dtype=np.float32).reshape(10, 3)
    calls = []

    def bounds():
        calls.append(1)
        return p.min(axis=0), p.max(axis=0)
    lo, _ = memo_by_content("test.bounds", (p,), (), bounds)
    memo_by_content("test.bounds", (p,), (), bounds)
    assert len(calls) == 1  # unchanged content: remembered
    p[3, 1] = -5.0  # in place: same object, same id
    lo2, _ = memo_by_content("test.bounds", (p,), (), bounds)
    assert len(calls) == 2 and lo2[1] == -5.0 and lo[1] == 1.0
    memo_by_content("test.bounds", (p,), ("other params",), bounds)
    assert len(calls) == 3  # other parameters: another value
    # Mesh.bounds hands out copies: editing them leaves the remembered value alone
    sc = _scene()
    lo, hi = sc.mesh.bounds
    lo[:] = 99.0
    assert np.array_equal(sc.mesh.bounds[0], sc.mesh.positions.min(axis=0))
    sc.mesh.positions[:, 0] *= 2.0
    assert np.array_equal(sc.mesh.bounds[1], sc.mesh.positions.max(axis=0))


def test_memo_by_content_keeps_at_most_keep_values_of_a_name():
    """Large remembered values (the interreflection's merged hits, ~50-80 MB per head) are bounded per
    name: a batch of many meshes holds ``keep`` of them, not the shared memo's 64."""
    from dermis import invalidation

    arrays = [np.full(4, i, np.float32) for i in range(5)]
    for i, a in enumerate(arrays):
        memo_by_content("test.big", (a,), (), lambda i=i: i, keep=2)
        memo_by_content("test.small", (a,), (), lambda i=i: i)
    held = [slot for slot in invalidation._MEMO if slot[0] == "test.big"]
    assert len(held) == 2 and [invalidation._MEMO[s][1] for s in held] == [3, 4]  # the newest two
    assert sum(slot[0] == "test.small" for slot in invalidation._MEMO) == 5  # other names untouched
    calls = []
    assert memo_by_content("test.big", (arrays[4],), (), lambda: calls.append(1)) == 4 and not calls


def test_framed_camera_follows_an_in_place_mesh_edit_and_a_new_up():
    sc = _scene()
    m = sc.mesh

    def expected(cam):
        return fit_camera(cam, head_vertices(m.positions, cam.up), 1.5)
    assert framed_camera(sc.camera, m, 1.5) == expected(sc.camera)
    m.positions[:] *= 1.7  # the sphere grows: the fitted camera backs off
    grown = framed_camera(sc.camera, m, 1.5)
    assert grown == expected(sc.camera)
    tilted = dataclasses.replace(sc.camera, up=(0.2, 1.0, 0.0))
    assert framed_camera(tilted, m, 1.5) == expected(tilted)
    moved = dataclasses.replace(sc.camera, position=(1.0, 0.5, 4.0))  # the fit is kept per view too
    assert framed_camera(moved, m, 1.5) == expected(moved) != expected(sc.camera)
    assert framed_camera(sc.camera, m, 1.2) == fit_camera(sc.camera, head_vertices(m.positions, sc.camera.up), 1.2)
    assert m.positions.flags.writeable  # the memo's copies are read-only, the mesh's arrays are not


def test_set_uniform_writes_changes_only_and_the_program_holds_each_value(gl_ctx):
    from dermis.gl.resources import set_uniform

    prog = gl_ctx.program(
        vertex_shader="#version 450 core\nuniform vec3 uV; uniform float uF; uniform int uI[2];\n"
                      "out vec4 c; void main() { c = vec4(uV, uF + float(uI[0] + uI[1])); gl_Position = vec4(0.0); }",
        fragment_shader="#version 450 core\nin vec4 c; out vec4 f; void main() { f = c; }")
    writes = []
    for name in ("uV", "uF", "uI"):
        u = prog[name]
        real = u.write
        u.write = lambda data, real=real, name=name: writes.append(name) or real(data)
    set_uniform(prog, "uV", (1.0, 2.0, 3.0))
    set_uniform(prog, "uV", (1.0, 2.0, 3.0))
    set_uniform(prog, "uV", np.array([1.0, 2.0, 3.0]))  # the same bytes by another route
    assert writes == ["uV"]
    set_uniform(prog, "uV", (1.0, 2.0, 4.0))
    set_uniform(prog, "uF", 0.5)
    set_uniform(prog, "uI", [3, 4])
    set_uniform(prog, "uI", [3, 4])
    set_uniform(prog, "uMissing", 1.0)  # dropped by the compiler / absent: ignored
    assert writes == ["uV", "uV", "uF", "uI"]
    assert prog["uV"].value == (1.0, 2.0, 4.0) and prog["uF"].value == 0.5 and prog["uI"].value == [3, 4]
    prog.release()


def test_every_change_between_cached_frames_equals_a_fresh_renderer(gl_ctx):
    """One Renderer through a sequence of changes (camera, light colour and direction, in-place
    albedo, profile and mesh edits, the scale), every frame against a fresh Renderer's: the
    remembered keys, bounds, framing, light fits, blur plan, profile uniforms and uniform values
    never show a stale value. Each change alters the image (checked), so a stale cache would fail."""
    sc = _scene()
    changes = [
        ("camera", lambda: setattr(sc.camera, "position", (1.2, 0.6, 3.5))),
        ("light colour", lambda: setattr(sc.lights[1], "color", (1.0, 0.3, 0.2))),
        ("light direction", lambda: setattr(sc.lights[0], "direction", (-0.2, -0.5, -0.8))),
        ("albedo in place", lambda: sc.material.albedo.data.__imul__(0.6)),
        ("profile in place", lambda: sc.profile.variances_mm2.__imul__(3.0)),
        ("mesh in place", lambda: sc.mesh.positions.__imul__(0.8)),
        ("scale", lambda: setattr(sc, "mm_per_unit", 35.0)),
        ("shadow softness", lambda: setattr(sc.lights[0], "shadow_softness", 6.0)),
        ("environment colour", lambda: setattr(sc.environment, "color", (0.3, 0.2, 0.1))),
        ("pores", lambda: (setattr(sc.material, "pore_strength", 0.8), setattr(sc.material, "pore_scale_mm", 40.0))),
        ("albedo swapped", lambda: setattr(sc.material, "albedo", Texture(np.full((8, 8, 3), 0.2, np.float32), "test:grey"))),
        ("camera again", lambda: setattr(sc.camera, "position", (-0.5, 0.2, 3.8))),
    ]
    with Renderer(sc, (32, 32), ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=256) as r:
        prev = r.render("tsd")
        r.render("lambert")  # another technique in between: its programs hold their own values
        assert np.array_equal(r.render("tsd"), prev)
        for what, change in changes:
            change()
            img = r.render("tsd")
            assert np.abs(img - prev).max() > 1e-4, f"{what}: the change did not alter the image"
            np.testing.assert_allclose(img, _fresh(sc, "tsd", gl_ctx), atol=1e-5, err_msg=what)
            np.testing.assert_allclose(r.render("lambert"), _fresh(sc, "lambert", gl_ctx), atol=1e-6, err_msg=what)
            prev = img


def test_validation_fast_paths_refuse_what_the_full_checks_refuse():
    from dermis.validation import check_scene

    for attr, bad, match in (("intensity", float("nan"), "intensity"), ("intensity", True, "intensity"),
                             ("intensity", 10 ** 400, "intensity"), ("color", (2e13, 0.0, 0.0), "color"), ("color", (-0.1, 0.0, 0.0), "color"),
                             ("direction", (0.0, 0.0, float("inf")), "direction"),
                             ("direction", (0.0, 0.0, 0.0), "direction"), ("shadow_softness", -1.0, "shadow_softness")):
        sc = _scene()
        setattr(sc.lights[0], attr, bad)
        with pytest.raises(DermisError, match=match):
            check_scene(sc, full=False)
    check_scene(_scene(), full=False)


def test_extreme_points_give_the_same_fits_as_every_vertex():
    """The view and shadow-map fits on the hull's points (dermis.geometry.hull) equal, bit for bit,
    the fits on every vertex, for random views and light directions; degenerate clouds keep all."""
    from dermis.camera import light_matrices
    from dermis.framing import _box_centre, fit_camera
    from dermis.geometry.hull import extreme_points

    rng = np.random.default_rng(7)
    sc = _scene()
    sc.mesh.positions[:] += rng.normal(scale=0.02, size=sc.mesh.positions.shape).astype(np.float32)  # a lumpy sphere
    p = sc.mesh.positions.astype(np.float64)
    q = extreme_points(p)
    assert 4 <= len(q) < len(p) and q.flags.c_contiguous
    lo, hi = sc.bounds()
    c = _box_centre(p)
    for _ in range(300):
        d = rng.normal(size=3)
        assert (p @ d).max() == (q @ d).max()
        L = dataclasses.replace(sc.lights[0], direction=tuple(d))
        a, b = light_matrices(L, lo, hi, p), light_matrices(L, lo, hi, q)
        assert np.array_equal(a[0], b[0]) and a[2] == b[2]
        cam = dataclasses.replace(sc.camera, position=tuple(rng.normal(size=3) * 5.0), fov_deg=float(rng.uniform(10, 80)))
        aspect = float(rng.uniform(0.5, 2.0))
        assert fit_camera(cam, p, aspect, centre=c) == fit_camera(cam, q, aspect, centre=c)
    flat = np.c_[rng.random((50, 2)), np.zeros(50)]
    assert np.array_equal(extreme_points(flat), flat)  # no 3-D hull: every point
    assert np.array_equal(extreme_points(p[:4]), p[:4])


def test_product_keys_with_memory_equal_fresh_keys():
    """ProductKeys (the Renderer's: only changed inputs written out again) gives the keys a fresh
    product_keys gives, through a sequence of changes, and a product keeps its key exactly when
    none of its inputs changed."""
    from dermis.invalidation import PRODUCTS, ProductKeys, product_keys, scene_inputs

    sc = _scene()
    keys = ProductKeys()
    changes = [lambda: None, lambda: setattr(sc.camera, "position", (1.0, 0.2, 3.0)),
               lambda: setattr(sc.lights[0], "direction", (0.1, -0.9, -0.3)),
               lambda: sc.material.albedo.data.__imul__(0.5), lambda: sc.mesh.positions.__imul__(1.1),
               lambda: setattr(sc, "mm_per_unit", 30.0), lambda: setattr(sc.lights[1], "intensity", 2.0)]
    prev_inputs = prev = None
    for change in changes:
        change()
        inputs = scene_inputs(sc, irradiance_size=64, epoch=0)
        got = keys(inputs)
        assert got == product_keys(inputs)
        if prev is not None:
            for product, names in PRODUCTS.items():
                same = all(inputs[n] == prev_inputs[n] for n in names)
                assert (got[product] == prev[product]) == same, product
        prev_inputs, prev = inputs, got


def test_frame_scope_hashes_an_array_once_and_forgets_on_exit(monkeypatch):
    from dermis import invalidation

    calls = []
    real = invalidation._fingerprint
    monkeypatch.setattr(invalidation, "_fingerprint", lambda a: calls.append(1) or real(a))
    a = np.arange(12.0)
    with invalidation.frame_scope():
        k = invalidation.fingerprint(a)
        with invalidation.frame_scope():  # nested: the outer scope's memo
            assert invalidation.fingerprint(a) == k
        assert invalidation.fingerprint(a) == k and len(calls) == 1
    a[3] = -1.0  # between frames: seen
    assert invalidation.fingerprint(a) != k and len(calls) == 2
    assert invalidation.fingerprint(a) == invalidation.fingerprint(a) and len(calls) == 4  # no scope: each call hashes


def test_per_frame_validation_memo_still_refuses_a_value_changed_after_a_good_frame():
    """check_render_call remembers the parts of a scene that passed; a later bad value (also one
    edited in place in a list the scene holds) is refused as the full check refuses it."""
    from dermis.validation import check_render_call

    def bad(edit, match):
        sc = _scene()
        sc.lights[0].color = [1.0, 1.0, 1.0]  # a list: edited in place below
        sc.lights[1].intensity = 1.0
        check_render_call(sc, None)
        check_render_call(sc, None)  # remembered
        edit(sc)
        with pytest.raises(DermisError, match=match):
            check_render_call(sc, None)
    bad(lambda sc: sc.lights[0].color.__setitem__(0, -1.0), "color")
    bad(lambda sc: setattr(sc.lights[1], "intensity", float("nan")), "intensity")
    bad(lambda sc: setattr(sc.material, "roughness", 0.0), "roughness")
    bad(lambda sc: setattr(sc.camera, "up", (0.3, 0.4, 4.0)), "up")  # along the view direction
    bad(lambda sc: setattr(sc.camera, "position", sc.camera.target), "coincide")
    bad(lambda sc: setattr(sc.camera, "fov_deg", 170.0), "fov")
    bad(lambda sc: setattr(sc.output, "exposure", 100.0), "exposure")
    bad(lambda sc: sc.lights.append(Light(direction=(0.0, 0.0, 0.0))), "direction")
    bad(lambda sc: setattr(sc.lights[1], "intensity", True), "intensity")  # True == 1.0: a snapshot must tell them apart
    bad(lambda sc: setattr(sc.output, "bloom", np.float32("nan")), "bloom")


def test_tsd_prepared_passes_follow_options_and_sizes(gl_ctx):
    """tsd draws its blur chain from a prepared list (programs, framebuffers, uniform bytes): a
    change of options (taps, levels) or of the irradiance size gives a fresh Renderer's image."""
    sc = _scene()
    with Renderer(sc, (32, 32), ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=256) as r:
        before = r.render("tsd")
        for opts, size in (({"max_taps": 2}, 64), ({"max_taps": 2, "multires": False}, 64), ({"multires": False}, 128)):
            r.technique("tsd", **opts)
            if size != r.irradiance_size:
                r.set_irradiance_size(size)
            sc.lights[0].intensity *= 1.1  # and a lights-moving frame after it
            for _ in range(2):
                img = r.render("tsd")
                with Renderer(sc, (32, 32), ctx=gl_ctx, samples=0, irradiance_size=size, shadow_size=256) as fresh:
                    fresh.technique("tsd", **dataclasses.asdict(r.technique("tsd").options))
                    np.testing.assert_allclose(img, fresh.render("tsd"), atol=1e-5, err_msg=f"{opts} {size} {_}")
        assert np.abs(img - before).max() > 1e-4


def test_a_camera_only_frame_prepares_only_the_per_frame_uniforms(gl_ctx, monkeypatch):
    """The fast path: once a frame has set a program up, a frame where only the camera moved does
    not even compute the bytes of the scene's uniforms (lights, shadows, material, profile: held by
    the programs, dermis.gl.resources.prepared), and writes only the camera's; a frame whose
    lights changed computes and writes the lights' again."""
    import moderngl

    from dermis.gl import resources

    sc = _scene()
    computed, written = [], []
    real_bytes, real_write = resources.uniform_bytes, moderngl.Uniform.write
    # (uPixelRadians: the camera's pixel angle, common/mesh_varyings.glsl; written only when fov or size change)
    per_frame = {"uViewProj", "uCameraPos", "uTranslucency", "uPoreScaleMm", "uPoreStrength", "uOutputMode", "uViewZ",
                 "uScattered", "uDirectionalAlbedo", "uSharpShadow", "uPixelRadians",
                 # round 22 (view22): the baked transfer's view term in the final passes, set every frame, written on change
                 "uTransferLevel", "uTransferIndex", "uTransferViewMean"}
    with Renderer(sc, (32, 32), ctx=gl_ctx, samples=0, irradiance_size=64, shadow_size=256) as r:
        monkeypatch.setattr(resources, "uniform_bytes", lambda u, v: computed.append(u.name) or real_bytes(u, v))
        monkeypatch.setattr(moderngl.Uniform, "write", lambda u, data: written.append(u.name) or real_write(u, data))
        for tech in ("tsd", "lambert", "preintegrated"):
            r.render(tech)
            r.render("tsd")  # another technique in between
            sc.camera.position = (0.2 + 0.1 * len(written), 0.5, 4.0)
            computed.clear()
            written.clear()
            r.render(tech)
            assert set(written) == {"uViewProj", "uCameraPos"}, (tech, written)
            assert set(computed) <= per_frame | {"uDiffuseTable", "uPenumbraTable", "uThicknessMap", "uFarFaceMap", "uTranslucencyMinVariance",
                                                 "uTranslucencyStrength", "uCurvatureMaxPerMm", "uPenumbraWidthRangeMm",
                                                 "uCurvatureFromMesh", "uScatterRadiusMm", "uBlurredNormals",
                                                 "uPenumbraScattering", "uGaussianCount", "uWeights", "uVariances",
                                                 "uSlabReducedAlbedo", "uSlabKappa", "uSlabSourceDepth", "uSlabExtrapolation",
                                                 "uSlabAlbedo", "uFoldScattering", "uShadowDepth", "uNormalMapLod",
                                                 "uTransfer", "uTransferLevel"}, (tech, computed)
            if tech != "preintegrated":  # tsd's and lambert's final passes: the per-frame ones alone
                assert set(computed) <= per_frame and "uLightRadiance" not in computed, (tech, computed)
        sc.lights[1].color = (0.2, 0.9, 0.4)
        written.clear()
        r.render("tsd")
        assert "uLightRadiance" in written
