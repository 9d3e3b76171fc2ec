"""dermis batch: sweep files, parameters on a Scene, executors (local, Ray), the dataset.

The rendering tests share one small sweep (a plane seen face-on, 64x64, 12 renders of which 6
fail on a broken environment map) rendered once per executor: 2 local workers, 1 local worker
interrupted with SIGINT and resumed, and a local Ray with 2 actors; all must give the same
images.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from dermis.batch.apply import place_camera, spherical_offset
from dermis.batch.sweep import expand, load_sweep, render_id
from dermis.environment import rotate_equirect
from dermis.errors import DermisError

REPO = Path(__file__).resolve().parent.parent

PLANE_SCENE = """
[scene]
name = "plane"
mm_per_unit = 10.0
technique = "tsd"

[mesh]
builtin = "plane"

[[lights]]
type = "directional"
direction = [0.3, -0.4, -0.866]
intensity = 3.0
"""

SWEEP = """
[sweep]
name = "test-sweep"
mode = "grid"
irradiance_size = 128
shadow_size = 256
outputs = ["png", "exr", "mask", "depth"]

[axes]
scene = "plane.toml"
size = "64x64"
camera.elevation_deg = 0.0
camera.distance = 5.0
camera.azimuth_deg = [0.0, 20.0, -20.0]
lights.temperature_k = [2700.0, 6500.0]
environment.image = ["none", "broken.hdr"]
"""
N_RENDERS, N_FAILED = 12, 6


def _write_sweep(folder: Path, text: str = SWEEP, name: str = "sweep.toml") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "plane.toml").write_text(PLANE_SCENE)
    (folder / "broken.hdr").write_bytes(b"#?RADIANCE\nthis is not an image\n")
    (folder / name).write_text(text)
    return folder / name


def _rows(out: Path) -> list[dict]:
    from dermis.batch.dataset import read_table

    return read_table(out).to_pylist()


# ------------------------------------------------------------------------------ no GL
def test_grid_expansion_order_and_ids(tmp_path):
    sweep = load_sweep(_write_sweep(tmp_path))
    specs = expand(sweep)
    assert len(specs) == N_RENDERS
    # the first axis in the file varies slowest; fixed axes are constant
    az = [s.params["camera.azimuth_deg"] for s in specs]
    env = [s.params["environment.image"] for s in specs]
    assert az == [0.0] * 4 + [20.0] * 4 + [-20.0] * 4
    assert env == ["none", "broken.hdr"] * 6
    assert {s.params["size"] for s in specs} == {"64x64"}
    assert [s.index for s in specs] == list(range(N_RENDERS))
    assert len({s.render_id for s in specs}) == N_RENDERS
    assert specs[0].render_id == render_id(specs[0].params)
    # parsing again gives the same list (ids are a hash of the parameters, not of the run)
    assert [s.render_id for s in expand(load_sweep(tmp_path / "sweep.toml"))] == [s.render_id for s in specs]


def test_random_draws_are_seeded_and_prefix_stable(tmp_path):
    text = """
[sweep]
mode = "random"
count = {count}
seed = {seed}
[axes]
skin.melanin = {{uniform = [0.01, 0.4]}}
lights.intensity = {{loguniform = [0.5, 2.0]}}
skin.profile = ["fair", "dark"]
"""
    def draws(count, seed):
        p = tmp_path / f"r{count}_{seed}.toml"
        p.write_text(text.format(count=count, seed=seed))
        return expand(load_sweep(p))

    a, b, c, d = draws(50, 3), draws(50, 3), draws(80, 3), draws(50, 4)
    assert [s.params for s in a] == [s.params for s in b]
    assert [s.render_id for s in c[:50]] == [s.render_id for s in a]  # more draws keep the first ones
    assert [s.params for s in d] != [s.params for s in a]
    mel = np.array([s.params["skin.melanin"] for s in c])
    inten = np.array([s.params["lights.intensity"] for s in c])
    assert mel.min() >= 0.01 and mel.max() <= 0.4 and inten.min() >= 0.5 and inten.max() <= 2.0
    assert {s.params["skin.profile"] for s in c} == {"fair", "dark"}
    # loguniform: log of the draws uniform on [log 0.5, log 2], median near 1 (not 1.25)
    assert abs(np.median(inten) - 1.0) < 0.25


@pytest.mark.parametrize("body, message", [
    ("[axes]\ncamera.azimuth = [0, 1]", "unknown axis 'camera.azimuth'"),
    ("[sweep]\nmode = \"spiral\"", "mode must be grid or random"),
    ("[sweep]\nmode = \"random\"", "needs count >= 1"),
    ("[axes]\nskin.melanin = {uniform = [0, 1]}", "not available in mode = \"grid\""),
    ("[axes]\ntechnique = [\"tsd\", \"nope\"]", "technique 'nope' is unknown"),
    ("[axes]\nsize = \"64x\"", "expected WxH"),
    ("[axes]\nscene = \"missing.toml\"", "scene 'missing.toml' not found"),
    ("[sweep]\noutputs = [\"exr\"]", "outputs must include \"png\""),
    ("[axes]\nskin.melanin = [\"a\"]", "must be finite numbers"),
])
def test_sweep_errors_name_the_problem(tmp_path, body, message):
    p = tmp_path / "bad.toml"
    p.write_text(body)
    with pytest.raises(DermisError, match=message.replace("(", r"\(").replace(")", r"\)")) as exc:
        load_sweep(p)
    assert "\n" not in str(exc.value) and "bad.toml" in str(exc.value)


def test_blackbody_colours_against_cie_references():
    """2856 K is CIE illuminant A (CIE 15:2004, x = 0.44757, y = 0.40745); 6500 K checked
    against an independent numpy integration of Planck's law with the CIE 1931 tables."""
    import colour

    from dermis.batch.colour_temperature import LUMINANCE_RGB, blackbody_rgb, blackbody_xy

    assert np.allclose(blackbody_xy(2856.0), [0.44757, 0.40745], atol=1e-4)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    lam = cmfs.wavelengths * 1e-9
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    planck = 2 * h * c**2 / lam**5 / np.expm1(h * c / (lam * k * 6500.0))
    xyz = (planck[:, None] * cmfs.values).sum(axis=0)
    assert np.allclose(blackbody_xy(6500.0), xyz[:2] / xyz.sum(), atol=2e-5)
    # linear sRGB with luminance 1; warm lights red-heavy, hot ones blue-heavy
    for t in (1500.0, 2700.0, 6500.0, 12000.0):
        assert float(LUMINANCE_RGB @ np.array(blackbody_rgb(t))) == pytest.approx(1.0, abs=1e-9)
    r, g, b = blackbody_rgb(2700.0)
    assert r > g > b > 0
    r, g, b = blackbody_rgb(12000.0)
    assert b > g and b > r
    with pytest.raises(DermisError, match="temperature_k"):
        blackbody_rgb(500.0)


def test_environment_rotation_moves_directions_about_y():
    """A bright texel seen along d is seen along R_y(theta) d after rotate_equirect(theta)."""
    from dermis.environment import equirect_directions

    h, w = 16, 64
    img = np.zeros((h, w, 3), np.float32)
    img[5, 11] = 1.0
    dirs, _ = equirect_directions(h, w)
    d = dirs[5, 11]
    for deg in (90.0, 45.0, -33.75, 360.0):  # multiples of 360 / 64: exact column shifts
        out = rotate_equirect(img, deg)
        i, j = np.unravel_index(np.argmax(out[:, :, 0]), out.shape[:2])
        t = math.radians(deg)
        expect = np.array([d[0] * math.cos(t) + d[2] * math.sin(t), d[1], -d[0] * math.sin(t) + d[2] * math.cos(t)])
        assert np.allclose(dirs[i, j], expect, atol=1e-6), deg
        assert out[:, :, 0].sum() == pytest.approx(1.0)
    # in between: linear interpolation keeps the total and splits the texel across two columns
    half = rotate_equirect(img, 360.0 / w / 2)
    assert half[:, :, 0].sum() == pytest.approx(1.0) and np.count_nonzero(half[:, :, 0]) == 2


def test_camera_placement_on_its_sphere():
    from dermis.scene.model import Camera

    cam = Camera(position=(0.0, 2.0, 10.0), target=(0.0, 2.0, 0.0), fov_deg=30.0)
    place_camera(cam, azimuth_deg=90.0)
    assert np.allclose(cam.position, (10.0, 2.0, 0.0), atol=1e-9)  # +z turned toward +x
    place_camera(cam, elevation_deg=30.0, distance=4.0, fov_deg=20.0)
    az, el, dist = spherical_offset(cam)
    assert (az, el, dist) == pytest.approx((90.0, 30.0, 4.0))
    assert cam.position[1] == pytest.approx(2.0 + 4.0 * 0.5) and cam.fov_deg == 20.0
    with pytest.raises(DermisError, match="camera.distance"):
        place_camera(cam, distance=0.0)


def test_parameters_applied_to_a_scene_and_reset(tmp_path):
    """Lights turn about +y through the mesh centre; intensity scales; a render's changes do not
    leak into the next (the worker keeps one Scene object for the Renderer)."""
    import dermis
    from dermis.batch.apply import SceneState, apply_parameters

    _write_sweep(tmp_path)
    scene = dermis.load_scene(tmp_path / "plane.toml")
    state = SceneState(scene)
    d0 = np.array(scene.lights[0].direction)
    derived = apply_parameters(state, {"lights.rotation_deg": 90.0, "lights.intensity": 2.0,
                                       "skin.profile": "deon", "camera.fov_deg": 12.0})
    d1 = np.array(scene.lights[0].direction)
    assert np.allclose(d1, [d0[2], d0[1], -d0[0]], atol=1e-9)  # R_y(90): (x, y, z) -> (z, y, -x)
    assert scene.lights[0].intensity == pytest.approx(6.0) and derived["light_intensities"] == [pytest.approx(6.0)]
    assert scene.camera.fov_deg == 12.0
    apply_parameters(state, {})
    assert np.allclose(scene.lights[0].direction, d0) and scene.lights[0].intensity == 3.0
    assert scene.camera.fov_deg != 12.0
    with pytest.raises(DermisError, match="melanin"):
        apply_parameters(state, {"skin.profile": "physical", "skin.melanin": 1.5, "skin.hemoglobin": 0.01})


def test_environment_rotation_is_set_on_the_scene_not_baked_into_a_copy(tmp_path):
    """A sweep's environment.rotation_deg turns the scene's own image by its rotation_deg (added to
    the scene's), keeps the image object (one SH projection / prefiltered map per angle, not a
    rotated copy per render), and resets with the scene."""
    import dermis
    from dermis.batch.apply import SceneState, apply_parameters
    from dermis.scene.model import Texture

    _write_sweep(tmp_path)
    scene = dermis.load_scene(tmp_path / "plane.toml")
    image = Texture(np.random.default_rng(1).random((8, 16, 3)).astype(np.float32), "sky.exr")
    scene.environment.image, scene.environment.rotation_deg = image, 30.0
    state = SceneState(scene)
    loads = []
    apply_parameters(state, {"environment.rotation_deg": 45.0},
                     environment_image=lambda src: loads.append(src) or src)
    assert scene.environment.image is image and loads == [image]
    assert scene.environment.rotation_deg == pytest.approx(75.0)
    apply_parameters(state, {})
    assert scene.environment.rotation_deg == pytest.approx(30.0)


def test_batch_cli_errors_are_one_line(tmp_path, monkeypatch, capsys):
    from dermis.cli import main

    sweep = _write_sweep(tmp_path)
    occupied = tmp_path / "occupied"
    occupied.mkdir()
    (occupied / "keep.txt").write_text("mine")
    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    for args, message in ((["--out", str(tmp_path / "o1"), "--ray", "auto"], "pip install 'dermis[ray]'"),
                          (["--out", str(occupied)], "not empty and holds no dermis batch dataset"),
                          (["--out", str(tmp_path / "o2"), "--workers", "0"], "--workers: must be >= 1")):
        with pytest.raises(SystemExit) as exc:
            main(["batch", str(sweep), *args])
        err = capsys.readouterr().err.strip()
        assert exc.value.code == 2 and err.startswith("dermis: error:") and "\n" not in err and message in err, err
    assert not (tmp_path / "o1").exists() and (occupied / "keep.txt").read_text() == "mine"
    with pytest.raises(SystemExit) as exc:
        main(["batch", str(sweep), "--out", str(tmp_path / "o3"), "--dry-run"])
    assert exc.value.code == 0 and f"{N_RENDERS} renders (grid), {N_RENDERS} left" in capsys.readouterr().out


# ------------------------------------------------------------------------------ rendering
@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """The test sweep through 2 local worker processes."""
    from dermis.batch import run_batch

    folder = tmp_path_factory.mktemp("batch_local")
    sweep = _write_sweep(folder)
    result = run_batch(sweep, folder / "data", workers=2, progress=False)
    return result, folder / "data"


def _checksums(rows) -> dict:
    return {r["render_id"]: r["png_sha256"] for r in rows if r["status"] == "ok"}


def test_local_executor_dataset(local_run):
    from dermis.batch.colour_temperature import blackbody_rgb
    from dermis.batch.dataset import metadata_schema, read_table
    from dermis.images import read_image
    from dermis.output import output_transform

    result, out = local_run
    assert (result.ok, result.failed, result.skipped, result.interrupted) == (N_RENDERS - N_FAILED, N_FAILED, 0, False)
    table = read_table(out)
    assert table.schema.equals(metadata_schema(), check_metadata=False)
    rows = table.to_pylist()
    assert [r["index"] for r in rows] == list(range(N_RENDERS))  # one row per render, in list order
    assert len({r["worker"] for r in rows if r["status"] == "ok"}) == 2  # both workers rendered
    for r in rows:
        assert r["dermis_version"] and r["sweep"] == "test-sweep" and r["size"] == "64x64"
        if r["environment.image"] == "broken.hdr":  # failed, recorded with its one-line error, no files
            assert r["status"] == "failed" and "broken.hdr" in r["error"] and "\n" not in r["error"]
            assert r["png"] is None
            continue
        assert r["status"] == "ok" and r["error"] is None and r["gl_renderer"]
        assert (r["width"], r["height"]) == (64, 64) and r["render_ms"] > 0 and r["total_ms"] >= r["render_ms"]
        assert r["cpu_ms"] > 0
        data = (out / r["png"]).read_bytes()
        assert hashlib.sha256(data).hexdigest() == r["png_sha256"]
        assert r["light_colors"][0] == pytest.approx(list(blackbody_rgb(r["lights.temperature_k"])))
        png = read_image(out / r["png"], srgb=False)
        linear = read_image(out / r["exr"], srgb=False)
        mask = read_image(out / r["mask"], srgb=False)[:, :, 0]
        depth = read_image(out / r["depth"], srgb=False)[:, :, 0]
        assert png.shape[:2] == linear.shape[:2] == mask.shape == depth.shape == (64, 64)
        # the PNG is the linear EXR through the scene's output transform
        assert np.abs(output_transform(linear) - png[:, :, :3]).max() <= 1.0 / 255 + 1e-6
        # the plane covers the middle of the frame, not the corners; the mask says so and so does depth
        assert mask[32, 32] == 1.0 and mask[0, 0] == 0.0 and depth[0, 0] == 0.0
        # depth is sampled at pixel centres, the mask is MSAA coverage: fully covered pixels have a
        # depth, uncovered ones none (a straight edge cannot miss all samples and hit the centre)
        assert np.all(depth[mask == 1.0] > 0) and np.all(depth[mask == 0.0] == 0)
        if r["camera.azimuth_deg"] == 0.0:
            # face-on at 5 scene units: the depth of every plane pixel is 5 x 10 mm
            assert np.allclose(depth[depth > 0], 50.0, rtol=1e-6)
            assert np.allclose(r["camera_position"], [0.0, 0.0, 5.0], atol=1e-9)
    # the scene's light temperatures change the image
    ok = [r for r in rows if r["status"] == "ok"]
    assert len({r["png_sha256"] for r in ok}) == len(ok)


def test_interrupt_then_resume_gives_the_same_dataset(local_run, tmp_path):
    """Ctrl-C (SIGINT) on `dermis batch` mid-run: exit 130, a table of what finished, every row's
    files there, no partial file; the re-run renders only the rest, and the images equal the
    2-worker run's (determinism across worker counts and render orders)."""
    from dermis.batch import run_batch

    _, local_out = local_run
    # a longer sweep than the shared one (the same 12 renders and 28 more at other azimuths): on a
    # quiet machine 12 tiny renders finish before the SIGINT lands
    azimuths = "[0.0, 20.0, -20.0, 10.0, -10.0, 30.0, -30.0, 40.0, -40.0, 5.0]"
    sweep = _write_sweep(tmp_path, SWEEP.replace("[0.0, 20.0, -20.0]", azimuths))
    n_long, n_failed_long = 40, 20
    out = tmp_path / "data"
    env = {**os.environ, "PYTHONPATH": str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.Popen([sys.executable, "-m", "dermis.cli", "batch", str(sweep), "--out", str(out), "-j", "1",
                             "--no-progress"], env=env, stderr=subprocess.PIPE, text=True,
                            # a test run started in the background (CI, `cmd &`) inherits SIGINT
                            # ignored, and Python then installs no KeyboardInterrupt handler
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    journal = out / "journal.jsonl"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if journal.is_file() and any(json.loads(x)["status"] == "ok" for x in journal.read_text().splitlines() if x):
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    err = proc.communicate(timeout=120)[1]
    if proc.returncode == 0 and len(_rows(out)) == n_long:  # a fast GPU can finish 40 tiny renders first
        pytest.skip("the batch finished before SIGINT arrived (renders too fast to interrupt here)")
    assert proc.returncode == 130, err
    assert "interrupted" in err and "resume" in err
    rows = _rows(out)
    journal_ids = {json.loads(x)["render_id"] for x in journal.read_text().splitlines() if x}
    assert 1 <= len(rows) < n_long and {r["render_id"] for r in rows} == journal_ids
    for r in rows:
        for k in ("png", "exr", "mask", "depth"):
            assert r["status"] != "ok" or (out / r[k]).is_file()
    assert not list(out.rglob(".*.part*"))
    done = sum(r["status"] == "ok" for r in rows)
    (out / "images" / ".x.png.abc.part.png").write_bytes(b"left by a killed run")

    result = run_batch(sweep, out, workers=1, progress=False)
    assert result.skipped == done and result.ok + result.skipped == n_long - n_failed_long
    assert result.failed == n_failed_long  # failed renders are tried again on a re-run
    assert not list(out.rglob(".*.part*"))
    # the renders both sweeps share (same parameters, same ids) have the 2-worker run's bytes
    resumed, local = _checksums(_rows(out)), _checksums(_rows(local_out))
    assert len(local) == N_RENDERS - N_FAILED and {k: resumed[k] for k in local} == local


def test_ray_executor_matches_local(local_run, tmp_path):
    """The same sweep on a local Ray with 2 actors gives the same images and table."""
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'dermis[ray]')")
    from dermis.batch import run_batch

    _, local_out = local_run
    sweep = _write_sweep(tmp_path)
    result = run_batch(sweep, tmp_path / "data", workers=2, ray="auto", progress=False)
    assert (result.ok, result.failed) == (N_RENDERS - N_FAILED, N_FAILED)
    assert result.startup["executor"] == "ray" and result.startup["workers"] == 2
    rows = _rows(tmp_path / "data")
    assert _checksums(rows) == _checksums(_rows(local_out))
    assert len({r["worker"] for r in rows if r["status"] == "ok"}) == 2
