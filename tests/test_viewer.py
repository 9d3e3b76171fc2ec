"""The interactive viewer (dermis.viewer): camera math, scripts, the GPU output transform, and
the real window loop under a virtual X server (Xvfb) driven by scripted input.

The window tests start their own Xvfb on a free display (``-displayfd``). Xvfb comes from the
Debian package ``xvfb``, which ``make test`` installs (scripts/ensure-system-packages.sh, the
same way as the GL packages); without it the window tests are skipped, or fail under CI=true.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from dermis.errors import DermisError

# ------------------------------------------------------------------ scenes and helpers
# a lit sphere: scattering shows at its terminator, so tsd and lambert differ there
SPHERE_SCENE = """
[scene]
name = "sphere"
mm_per_unit = 30.0

[mesh]
builtin = "sphere"

[[lights]]
type = "directional"
direction = [0.6, -0.3, -0.75]
color = [1.0, 0.95, 0.9]
intensity = 3.0

[camera]
position = [0.0, 0.3, 4.5]
target = [0.0, 0.0, 0.0]
fov_deg = 30.0
"""

WINDOW = (240, 180)  # small: llvmpipe on shared CPUs
IRRADIANCE = 128


@pytest.fixture(scope="module")
def sphere_toml(tmp_path_factory):
    p = tmp_path_factory.mktemp("viewer_scene") / "sphere.toml"
    p.write_text(SPHERE_SCENE)
    return p


def _luminance(img):
    return np.asarray(img, np.float64)[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def _read_png(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"), np.float64) / 255.0


@pytest.fixture(scope="module")
def xvfb_display():
    """A private Xvfb server for this module's window tests; yields its DISPLAY string."""
    exe = shutil.which("Xvfb")
    if exe is None:
        msg = "Xvfb is not installed (make test installs it: scripts/ensure-system-packages.sh xvfb xauth)"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(msg + "; CI must have it")
        pytest.skip(msg)
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen([exe, "-displayfd", str(write_fd), "-screen", "0", "1024x768x24", "-nolisten", "tcp",
                             "-noreset"], pass_fds=(write_fd,), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    os.close(write_fd)
    try:
        import select

        ready, _, _ = select.select([read_fd], [], [], 30)
        number = os.read(read_fd, 64).decode().strip() if ready else ""
        if not number:
            proc.kill()
            err = proc.stderr.read().decode(errors="replace")[-500:] if proc.stderr else ""
            pytest.fail(f"Xvfb did not start: {err}")
        yield f":{number}"
    finally:
        os.close(read_fd)
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()


@pytest.fixture(scope="module")
def viewer_cache(tmp_path_factory):
    """One dermis disk-cache folder for this module's `dermis view` processes: a fresh one (no user's
    or other test's products), shared so that the second process on reads back the first one's
    products (rho_dt table, profile fits, bakes: content-keyed, read back bit for bit) instead of
    building them again (round 20)."""
    return tmp_path_factory.mktemp("viewer-cache")


def run_viewer(display, scene_path, script: dict, tmp_path, *extra, timeout=240, sizes=True, cache=None):
    """Run ``dermis view`` under ``display`` with a script; returns (completed process, report).
    ``sizes``: give the irradiance and shadow sizes (else the viewer chooses them from the view).
    ``cache``: the dermis cache folder (None: a fresh one under ``tmp_path``)."""
    script = dict(script)
    script.setdefault("report", "report.json")
    sp = tmp_path / "script.json"
    sp.write_text(json.dumps(script))
    env = dict(os.environ, DISPLAY=display, DERMIS_CACHE_DIR=str(cache or tmp_path / "profile-cache"))
    env.pop("WAYLAND_DISPLAY", None)
    cmd = [sys.executable, "-m", "dermis.cli", "view", str(scene_path), "--size", f"{WINDOW[0]}x{WINDOW[1]}",
           "--script", str(sp), *extra]
    if sizes:  # the shadow size of _offline's Renderer (its default)
        cmd += ["--irradiance-size", str(IRRADIANCE), "--shadow-size", "2048"]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, res.stderr[-3000:]
    report = json.loads((tmp_path / script["report"]).read_text())
    return res, report


# ------------------------------------------------------------------ no window needed
def test_orbit_camera_math():
    from dermis.scene.model import Camera
    from dermis.viewer.camera_controls import ORBIT_DEG_PER_PIXEL, OrbitCamera

    cam = Camera(position=(1.0, 2.0, 8.0), target=(0.0, 1.0, 0.0), fov_deg=30.0)
    oc = OrbitCamera.from_camera(cam, scene_radius=1.0)
    np.testing.assert_allclose(oc.position, cam.position, atol=1e-9)  # starts where the scene's camera is
    d0 = oc.distance
    oc.orbit(100, 0)  # 100 px right: the eye turns 40 degrees about up, distance kept
    off0 = np.array(cam.position) - cam.target
    off1 = oc.position - oc.target
    assert np.linalg.norm(off1) == pytest.approx(d0)
    h0, h1 = off0[[0, 2]], off1[[0, 2]]
    angle = np.degrees(np.arccos(h0 @ h1 / np.linalg.norm(h0) / np.linalg.norm(h1)))
    assert angle == pytest.approx(100 * ORBIT_DEG_PER_PIXEL)
    assert off1[1] == pytest.approx(off0[1])  # a horizontal drag keeps the height
    oc.orbit(0, 10_000)  # pitch clamps short of the pole
    assert oc.pitch_deg == pytest.approx(89.0)
    oc.reset()
    np.testing.assert_allclose(oc.position, cam.position, atol=1e-9)
    # zoom: one step 10 % closer, clamped to the scene's scale
    oc.zoom(1)
    assert oc.distance == pytest.approx(d0 * 0.9)
    oc.zoom(1000)
    assert oc.distance == pytest.approx(0.05)
    # pan: the target moves in the image plane, the view direction is kept
    oc.reset()
    before = oc.direction.copy()
    oc.pan(50, 0, 500)
    right, up = oc.view_axes()
    moved = oc.target - np.array(cam.target)
    assert moved @ right < 0 and abs(moved @ up) < 1e-12
    np.testing.assert_allclose(oc.direction, before, atol=1e-12)


def test_light_orbit_moves_the_light_around_the_scene():
    from dermis.scene.model import Light
    from dermis.viewer.camera_controls import LightOrbit

    L = Light(kind="directional", direction=(0.0, 0.0, -1.0), position=(0.0, 0.0, 5.0))
    lo = LightOrbit((0.0, 0.0, 0.0), L, scene_radius=1.0)
    lo.drag(225, 0)  # 90 degrees to the right
    lo.apply(L)
    np.testing.assert_allclose(L.direction, (-1.0, 0.0, 0.0), atol=1e-9)  # it now shines from +x
    np.testing.assert_allclose(np.linalg.norm(L.position), 5.0)


def test_script_parsing_and_errors(tmp_path):
    from dermis.viewer.script import Script

    s = Script.from_dict({"actions": [{"frame": 0, "orbit": [3, 4], "screenshot": "a.png"},
                                      {"frame": 2, "set": {"melanin": 0.2}, "quit": True}], "quit_after": 3},
                         base_dir=tmp_path)
    assert s.before(0) == [{"orbit": [3, 4]}]
    assert s.after(0) == [{"screenshot": tmp_path / "a.png"}]
    assert s.before(1) == [] and s.done(3) and not s.done(2) and s.scales == ()
    assert Script.from_dict({"scales": [0.25, 1]}).scales == (0.25, 1.0)
    for bad, words in (({"actions": [{"orbit": [1, 2]}]}, "frame"),
                       ({"scales": [0.3]}, "'scales' must be"), ({"scales": 0.5}, "'scales' must be"),
                       ({"actions": [{"frame": 0, "spin": 1}]}, "unknown action 'spin'"),
                       ({"actions": [{"frame": 0, "orbit": [1]}]}, "[dx, dy]"),
                       ({"actions": [], "extra": 1}, "unknown key 'extra'"),
                       ({"quit_after": 0}, "quit_after")):
        with pytest.raises(DermisError, match=words.replace("[", r"\[").replace("]", r"\]")):
            Script.from_dict(bad)
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(DermisError, match="not valid JSON"):
        Script.from_file(p)


def test_viewer_params_are_checked():
    from dermis.viewer.params import ViewerParams

    p = ViewerParams()
    p.update({"melanin": 0.3, "technique": "lambert", "light_color": [1, 0.5, 0.25]})
    assert p.melanin == 0.3 and p.light_color == (1.0, 0.5, 0.25)
    with pytest.raises(DermisError, match="unknown parameter 'melanine'"):
        p.update({"melanine": 0.1})
    with pytest.raises(DermisError, match="melanin must lie in"):
        ViewerParams().update({"melanin": 2.0})
    with pytest.raises(DermisError, match="unknown technique"):
        ViewerParams().update({"technique": "raytrace"})
    p = ViewerParams()
    p.apply_preset("dark")
    from dermis.profiles.presets import SKIN_PRESETS

    dark = SKIN_PRESETS["dark"]
    assert (p.profile, p.melanin, p.hemoglobin) == ("dark", dark.melanin_fraction, dark.hemoglobin_fraction)


def test_scene_editor_colours_skin_only_with_spectral_profiles():
    from dermis.scene.builtin import builtin_mesh
    from dermis.scene.model import Scene
    from dermis.viewer.params import ProfileResult, SceneEditor, ViewerParams

    mesh, _, _ = builtin_mesh("sphere")
    scene = Scene(mesh=mesh)
    ed, p = SceneEditor(scene), ViewerParams.from_scene(scene)
    ed.apply(p)
    assert scene.skin_color == "albedo"  # the scene's own
    from dermis.profiles import deon_skin

    ed.apply_profile(ProfileResult(("fair", 0.005, 0.7, 0.005, 0.75, 0.25), deon_skin()))
    ed.apply(p)
    assert scene.skin_color == "profile"
    p.skin_color = "albedo"
    ed.apply(p)
    assert scene.skin_color == "albedo"
    p.skin_color = "profile"
    ed.apply_profile(ProfileResult(("deon",), deon_skin()))
    ed.apply(p)
    assert scene.skin_color == "albedo"  # d'Eon's table carries no colour


def test_gpu_output_transform_matches_numpy(gl_ctx):
    """The shader the window shows the image with is dermis.output.output_transform."""
    from dermis.output import output_transform
    from dermis.viewer.present import Presenter

    pres = Presenter(gl_ctx)
    rng = np.random.default_rng(0)
    img = rng.lognormal(-1.0, 1.5, (37, 53, 3)).astype(np.float32)  # HDR, 0.01 .. 50
    try:
        for exposure, tonemap in ((0.0, "aces"), (1.5, "aces"), (-1.0, "linear")):
            gpu = pres.transform(img, exposure, tonemap)
            # GPU pow/exp are approximate: within a quarter of an 8-bit step
            assert np.abs(gpu - output_transform(img, exposure, tonemap)).max() < 1e-3
    finally:
        pres.release()


def test_gpu_object_tracker_counts_live_objects(gl_ctx):
    from dermis.viewer.gpu_objects import GpuObjectTracker

    tr = GpuObjectTracker(gl_ctx).install()
    try:
        assert tr.counts() == {}
        tex = gl_ctx.texture((4, 4), 4)
        fbo = gl_ctx.framebuffer(color_attachments=[tex])
        assert tr.counts() == {"framebuffer": 1, "texture": 1}
        fbo.release()
        tex.release()
        assert tr.total() == 0
        gl_ctx.texture((4, 4), 4)  # dropped without release(): still alive in the driver
        assert tr.counts() == {"texture": 1}
    finally:
        tr.uninstall()


def test_no_display_is_one_clear_line(box_toml):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run([sys.executable, "-m", "dermis.cli", "view", str(box_toml)], env=env, capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert lines == ["dermis: error: no display available (DISPLAY is not set); "
                     "run under xvfb-run: xvfb-run -a dermis view ..."]


def test_bad_script_is_a_user_error(tmp_path, box_toml):
    sp = tmp_path / "s.json"
    sp.write_text(json.dumps({"actions": [{"frame": 0, "twist": 1}]}))
    res = subprocess.run([sys.executable, "-m", "dermis.cli", "view", str(box_toml), "--script", str(sp)],
                         capture_output=True, text=True, timeout=120, env=dict(os.environ, DISPLAY=":0"))
    assert res.returncode == 2 and "unknown action 'twist'" in res.stderr


# ------------------------------------------------------------------ the real window under Xvfb
def _offline(scene_path, technique, camera, irradiance_size=IRRADIANCE, shadow_size=2048):
    """The same frame rendered headless (EGL) with the Python API."""
    import dermis
    from dermis.renderer import Renderer

    scene = dermis.load_scene(scene_path)
    with Renderer(scene, WINDOW, irradiance_size=irradiance_size, shadow_size=shadow_size) as r:
        return r.render(technique, camera=camera), scene


def test_scripted_session_screenshots_follow_the_inputs(xvfb_display, viewer_cache, sphere_toml, tmp_path):
    """Orbit, technique switch and melanin, driven through the real GLFW window loop."""
    import dermis
    from dermis.output import output_transform
    from dermis.viewer.camera_controls import OrbitCamera

    script = {"actions": [
        {"frame": 0, "screenshot": "start.png"},
        {"frame": 1, "orbit": [150, -20], "screenshot": "orbit.png"},
        {"frame": 2, "set": {"technique": "lambert"}, "screenshot": "lambert.png"},
        {"frame": 3, "set": {"technique": "tsd", "profile": "physical", "melanin": 0.02}, "screenshot": "melanin_low.png"},
        {"frame": 4, "set": {"melanin": 0.3}, "screenshot": "melanin_high.png"},
        {"frame": 5, "window_screenshot": "window.png", "resources": True},
    ], "quit_after": 6}
    res, report = run_viewer(xvfb_display, sphere_toml, script, tmp_path, cache=viewer_cache)
    assert report["frames"] == 6
    shots = {n: _read_png(tmp_path / f"{n}.png") for n in ("start", "orbit", "lambert", "melanin_low", "melanin_high")}
    for img in shots.values():
        assert img.shape == (WINDOW[1], WINDOW[0], 3)

    # orbiting re-ran only the final pass (the texture-space passes are view-independent) ...
    assert report["passes_run"][1] == ["tsd_final"]
    assert "tsd_irradiance" in report["passes_run"][0]
    # ... changed the image ...
    assert np.abs(shots["orbit"] - shots["start"]).mean() > 0.02
    # ... and shows exactly the orbited view: the same frame rendered headless by the Python API
    scene = dermis.load_scene(sphere_toml)
    oc = OrbitCamera.from_camera(scene.camera, float(np.linalg.norm(np.subtract(*scene.bounds()[::-1])) / 2))
    oc.orbit(150, -20)
    for name, technique in (("orbit", "tsd"), ("lambert", "lambert")):
        expected, sc = _offline(sphere_toml, technique, oc.camera())
        want = output_transform(expected, sc.output.exposure, sc.output.tonemap)
        assert np.abs(shots[name] - want).mean() < 2.0 / 255, name

    # tsd -> lambert changes the image (no scattering: a harder terminator, other highlights)
    changed = np.abs(shots["lambert"] - shots["orbit"]).max(axis=2) > 2.0 / 255
    assert changed.mean() > 0.03
    # more melanin darkens the skin, and turns it browner (less blue relative to red)
    low, high = shots["melanin_low"], shots["melanin_high"]
    assert _luminance(high).mean() < 0.6 * _luminance(low).mean()
    assert np.abs(high - low).mean() > 0.05
    # the panel is drawn in the window (GUI pixels differ from the plain render there)
    window = _read_png(tmp_path / "window.png")
    assert window.shape == (WINDOW[1], WINDOW[0], 3)
    assert report["resources"][0]["counts"]["texture"] > 0


def test_gpu_objects_stay_constant_over_200_frames_of_changes(xvfb_display, viewer_cache, box_toml, tmp_path):
    """200 frames changing technique, material, light, environment, output, skin profile,
    irradiance resolution and buffer view, with the panel on: the live GPU objects, counted at
    the same point of each 40-frame cycle, do not grow."""
    cycle, frames = 40, 200
    changes = {0: {"technique": "lambert"}, 5: {"technique": "tsd"}, 8: {"roughness": 0.2}, 9: {"roughness": 0.25},
               11: {"rho_s": 0.25}, 12: {"mix": 0.3}, 13: {"exposure": 0.5},
               14: {"light_intensity": 4.0, "light_color": [1.0, 0.8, 0.7]},
               15: {"environment": "constant", "environment_intensity": 2.0},
               16: {"profile": "physical", "melanin": 0.02}, 18: {"melanin": 0.2}, 20: {"irradiance_size": 256},
               22: {"buffer": "irradiance"}, 24: {"buffer": "blur_2", "buffer_scale": "exposure"},
               25: {"buffer": "final", "buffer_scale": "auto"}, 26: {"irradiance_size": 128, "tonemap": "linear"},
               28: {"profile": "scene", "environment": "scene", "tonemap": "aces", "exposure": 0.0},
               30: {"roughness": 0.3, "rho_s": 0.18, "mix": 0.5, "light_intensity": 3.0,
                    "light_color": [1.0, 0.95, 0.9]}}
    actions = []
    for f in range(frames):
        ph = f % cycle
        a = {"frame": f, "orbit": [7, 1 if ph < 20 else -1]}
        if ph in changes:
            a["set"] = changes[ph]
        if ph == 32:
            a["light_drag"] = [10, 0]
        if ph in (34, 36):
            a["zoom"] = 1 if ph == 34 else -1
        if ph == cycle - 1:
            a["resources"] = True
        actions.append(a)
    # the reduced frames' scales set by frame number (every step, 8 dividing the cycle): each cycle draws the
    # same frames at the same sizes, whatever the machine's load (adapted to the frame time, a loaded machine's
    # scales wander, and a renderer first drew a program variant at a new size in the fourth cycle: one more
    # vertex array, in a parallel run of the suite, round 20)
    scales = [0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0, 0.5]
    res, report = run_viewer(xvfb_display, box_toml, {"actions": actions, "quit_after": frames, "scales": scales},
                             tmp_path, timeout=400, cache=viewer_cache)
    assert report["frames"] == frames
    reduced = [tuple(report["render_size"][f]) for f in range(frames) if report["quality"][f] == "interactive"]
    assert len(set(reduced)) == len(set(scales)), reduced  # the targets are resized: they must not leak either
    counts = [r["counts"] for r in report["resources"]]
    assert [r["frame"] for r in report["resources"]] == [39, 79, 119, 159, 199]
    assert counts[0]["texture"] > 10 and counts[0]["framebuffer"] > 5 and counts[0]["program"] > 3
    # the first cycle warms up both of the viewer's renderers (the progressive viewer's small
    # interactive renderer draws some technique x mesh pairs for the first time in the second
    # cycle: one vertex array each, and a light pass's program for the light count on first draw,
    # dermis.techniques.shared.LightCountPrograms); from then on nothing may grow
    for c in counts[2:]:
        assert c == counts[1], f"GPU objects grew: {counts}"
    assert counts[1]["program"] - counts[0]["program"] <= 4, counts  # at most the light passes, first drawn
    assert all(c["texture"] == counts[0]["texture"] for c in counts), counts


def test_progressive_frames_while_dragging_then_the_full_frame(xvfb_display, viewer_cache, sphere_toml, tmp_path):
    """While input is active the viewer draws reduced frames (smaller output; a light drag re-runs
    the texture space on the small interactive renderer); the first frame without input is the
    full frame, equal to the headless render of that view."""
    import dermis
    from dermis.output import output_transform
    from dermis.viewer.camera_controls import OrbitCamera

    script = {"actions": [{"frame": f, "orbit": [40, -5]} for f in (1, 2, 3)] +
                         [{"frame": 4, "screenshot": "refined.png"}] +
                         [{"frame": f, "light_drag": [30, 0]} for f in (6, 7)], "quit_after": 10}
    res, report = run_viewer(xvfb_display, sphere_toml, script, tmp_path, cache=viewer_cache)
    q = report["quality"]
    assert q == ["full", "interactive", "interactive", "interactive", "full", "idle",
                 "interactive", "interactive", "full", "idle"], q
    for f in (1, 2, 3, 6, 7):
        w, h = report["render_size"][f]
        assert w < WINDOW[0] and h < WINDOW[1], report["render_size"]
    for f in (0, 4, 8):
        assert report["render_size"][f] == list(WINDOW)
    # orbiting reuses the full renderer's texture space; a light drag re-runs it on the small one
    assert all(report["passes_run"][f] == ["tsd_final"] for f in (1, 2, 3))
    assert [report["texture_space"][f] for f in (6, 7)] == ["fast", "fast"]
    assert "tsd_irradiance" in report["passes_run"][6]
    assert "tsd_irradiance" in report["passes_run"][8] and report["texture_space"][8] == "full"
    # the refined frame is the headless render of the orbited view
    scene = dermis.load_scene(sphere_toml)
    oc = OrbitCamera.from_camera(scene.camera, float(np.linalg.norm(np.subtract(*scene.bounds()[::-1])) / 2))
    for _ in range(3):
        oc.orbit(40, -5)
    expected, sc = _offline(sphere_toml, "tsd", oc.camera())
    want = output_transform(expected, sc.output.exposure, sc.output.tonemap)
    assert np.abs(_read_png(tmp_path / "refined.png") - want).mean() < 2.0 / 255


def test_sizes_left_to_the_viewer_follow_the_zoom_at_the_refine(xvfb_display, viewer_cache, sphere_toml, tmp_path):
    """Without --irradiance-size / --shadow-size the viewer re-chooses both from the view
    (adaptive_sizes of the orbit camera and window) after a zoom: not in the reduced frames of the
    zoom, not in the full frame that refines them (drawn at the sizes in use, without re-running the
    texture space: issue 14's 2 s), but in the frame after that; that frame is the headless render at
    those sizes; a size the user then picks in the panel stays while the other keeps following the
    view."""
    import dermis
    from dermis.adaptive_resolution import adaptive_sizes
    from dermis.output import output_transform
    from dermis.viewer.camera_controls import OrbitCamera

    script = {"actions": [{"frame": 1, "zoom": 7}, {"frame": 3, "screenshot": "zoomed.png"},
                          {"frame": 4, "set": {"irradiance_size": 256}, "zoom": -7}, {"frame": 7, "zoom": 7}],
              "quit_after": 10}
    res, report = run_viewer(xvfb_display, sphere_toml, script, tmp_path, sizes=False, cache=viewer_cache)
    assert report["quality"] == ["full", "interactive", "full", "full", "interactive", "full", "full",
                                 "interactive", "full", "full"], report
    scene = dermis.load_scene(sphere_toml)
    oc = OrbitCamera.from_camera(scene.camera, float(np.linalg.norm(np.subtract(*scene.bounds()[::-1])) / 2))
    start = adaptive_sizes(scene, WINDOW, camera=oc.camera())
    oc.zoom(7)
    near = adaptive_sizes(scene, WINDOW, camera=oc.camera())
    assert near[0] > start[0] and near[1] > start[1], (start, near)  # the zoom changes both: the test can fail
    sizes = [tuple(s) for s in report["sizes"]]
    # the zoom's reduced frame and its refine keep the start's sizes; the frame after them takes the view's
    assert sizes[:4] == [start, start, start, near], sizes
    assert sizes[5:7] == [(256, near[1]), (256, start[1])] and sizes[8:] == [(256, start[1]), (256, near[1])], sizes
    assert "tsd_irradiance" not in report["passes_run"][2]  # the refine re-ran no texture-space pass
    assert "tsd_irradiance" in report["passes_run"][3]  # the new sizes re-ran the texture space
    expected, sc = _offline(sphere_toml, "tsd", oc.camera(), *near)
    want = output_transform(expected, sc.output.exposure, sc.output.tonemap)
    assert np.abs(_read_png(tmp_path / "zoomed.png") - want).mean() < 2.0 / 255


def test_the_image_is_framed_right_of_the_panel(xvfb_display, viewer_cache, tmp_path):
    """Issue 12: "the viewer frames the head in the area the panel leaves free". With the panel
    shown in a window that has room, the image is rendered for and drawn in the window's part right
    of the panel, the scene's fitted camera framed for that part: the window right of the panel is
    the screenshot, and the screenshot is `dermis render` at that part's size (the panel covers no
    skin). Fails where the image spans the whole window under the panel."""
    import dermis
    from dermis.output import output_transform
    from dermis.renderer import Renderer
    from dermis.viewer.gui import PANEL_MARGIN_PX, PANEL_WIDTH_PX

    scene_path = tmp_path / "fit.toml"
    scene_path.write_text(SPHERE_SCENE + "fit = true\n")
    window, reserve = (720, 160), 2 * PANEL_MARGIN_PX + PANEL_WIDTH_PX
    area = (window[0] - reserve, window[1])
    script = {"actions": [{"frame": 0, "screenshot": "shot.png", "window_screenshot": "window.png"}], "quit_after": 1}
    res, report = run_viewer(xvfb_display, scene_path, script, tmp_path, "--size", f"{window[0]}x{window[1]}",
                             "-t", "lambert", cache=viewer_cache)
    assert report["render_size"][0] == list(area), report["render_size"]
    shot, shown = _read_png(tmp_path / "shot.png"), _read_png(tmp_path / "window.png")
    assert shot.shape == (area[1], area[0], 3) and shown.shape == (window[1], window[0], 3)
    assert np.abs(shown[:, reserve:] - shot).mean() < 2.0 / 255
    scene = dermis.load_scene(scene_path)
    with Renderer(scene, area, irradiance_size=IRRADIANCE, shadow_size=2048) as r:
        want = output_transform(r.render("lambert"), scene.output.exposure, scene.output.tonemap)
    assert np.abs(shot - want).mean() < 2.0 / 255
    assert _luminance(shot).max() > 0.2  # the sphere is in the frame
    # the panel is drawn from the first frame on (its text: light pixels left of the image; ImGui
    # skips drawing a window in the frame it first fits to its content)
    assert (_luminance(shown[:, :reserve]) > 0.5).sum() > 200
