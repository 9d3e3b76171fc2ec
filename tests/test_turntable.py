"""Turntables (dermis.viewer.turntable): valid files with N frames; the view turns between frames."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from dermis.errors import DermisError

SIZE = (96, 72)
FRAMES = 6


def _differ(a, b) -> float:
    return float(np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64)).mean() / 255.0)


def test_gif_has_n_frames_and_turns(box_toml, tmp_path):
    import imageio.v3 as iio

    import dermis
    from dermis.viewer.turntable import turntable

    out = tmp_path / "spin.gif"
    res = turntable(dermis.load_scene(box_toml), out, frames=FRAMES, size=SIZE, technique="tsd",
                    irradiance_size=128, progress=False)
    assert res["frames"] == FRAMES and out.is_file()
    frames = iio.imread(out, index=None)
    assert frames.shape[:3] == (FRAMES, SIZE[1], SIZE[0])
    assert _differ(frames[0], frames[FRAMES // 2]) > 0.01
    assert not list(tmp_path.glob(".spin.gif.*"))  # no temporary file left behind
    # the usual permissions of a new file (as `dermis render`'s outputs), not the temporary name's 0600
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask
    # lights fixed to the head: texture space ran once, then only the final pass
    assert "tsd_irradiance" in res["passes_run"][0]
    assert all(p == ["tsd_final"] for p in res["passes_run"][1:])


def test_mp4_through_the_cli_with_orbiting_light(box_toml, tmp_path):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    out = tmp_path / "spin.mp4"
    res = subprocess.run([sys.executable, "-m", "dermis.cli", "turntable", str(box_toml), "--frames", str(FRAMES),
                          "--size", f"{SIZE[0]}x{SIZE[1]}", "--out", str(out), "--technique", "lambert", "--orbit-light"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "wrote" in res.stdout and f"{FRAMES} frames" in res.stdout
    assert "turntable" in res.stderr  # the progress bar (tqdm writes to stderr)
    n, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert n == FRAMES
    gen = imageio_ffmpeg.read_frames(str(out))
    meta = gen.__next__()
    w, h = meta["size"]
    assert (w, h) == SIZE
    frames = [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in gen]
    assert len(frames) == FRAMES
    assert _differ(frames[0], frames[FRAMES // 2]) > 0.01


def test_png_folder(box_toml, tmp_path):
    import dermis
    from dermis.viewer.turntable import turntable

    out = tmp_path / "frames"
    turntable(dermis.load_scene(box_toml), out, frames=3, size=(48, 48), technique="lambert", progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["frame_00000.png", "frame_00001.png", "frame_00002.png"]


def test_turntable_user_errors(box_toml, tmp_path):
    import dermis
    from dermis.viewer.turntable import turntable

    scene = dermis.load_scene(box_toml)
    with pytest.raises(DermisError, match="unsupported turntable output '.avi'"):
        turntable(scene, tmp_path / "x.avi", frames=2, size=(32, 32))
    with pytest.raises(DermisError, match="frames: must be"):
        turntable(scene, tmp_path / "x.gif", frames=0, size=(32, 32))
    res = subprocess.run([sys.executable, "-m", "dermis.cli", "turntable", str(box_toml), "--out",
                          str(tmp_path / "missing" / "x.gif")], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ))
    assert res.returncode == 2 and "does not exist" in res.stderr
