"""Image output (PNG, EXR), the output transform, atomic writes.

Files are read back with Pillow and OpenEXR directly; the sRGB (IEC 61966-2-1) and ACES
(Narkowicz 2015) curves are re-implemented here in float64 from their published formulas.
"""

from __future__ import annotations

import numpy as np
import OpenEXR
import pytest
from PIL import Image

from dermis.images import write_exr, write_png
from dermis.output import output_transform


def srgb_encode(x):
    """IEC 61966-2-1: 12.92 x below 0.0031308, else 1.055 x^(1/2.4) - 0.055 (input clamped to [0, 1])."""
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def aces_narkowicz(x):
    """Narkowicz 2015, "ACES Filmic Tone Mapping Curve": (x(ax + b)) / (x(cx + d) + e), clamped."""
    a, b, c, d, e = 2.51, 0.03, 2.43, 0.59, 0.14
    x = np.maximum(np.asarray(x, np.float64), 0.0)
    return np.clip(x * (a * x + b) / (x * (c * x + d) + e), 0.0, 1.0)


def read_exr(path):
    with OpenEXR.File(str(path), separate_channels=True) as f:
        (x0, y0), (x1, y1) = f.header()["dataWindow"]
        ch = f.channels()
        return (x1 - x0 + 1, y1 - y0 + 1), {k: np.asarray(v.pixels) for k, v in ch.items()}


def folder_names(p):
    return sorted(x.name for x in p.iterdir())


# ---------------------------------------------------------------------------------------------
# the transform


def test_srgb_and_aces_formulas_closed_form_points():
    # fixed points of the standards, computed by hand (not by the code under test)
    assert srgb_encode(1.0) == pytest.approx(1.0)
    assert srgb_encode(0.0031308) == pytest.approx(0.04045, abs=1e-6)
    assert srgb_encode(0.5) == pytest.approx(0.735356983, abs=1e-8)
    assert aces_narkowicz(1.0) == pytest.approx(2.54 / 3.16)
    # the module's transform at the same points
    y = output_transform(np.array([[[1.0, 0.5, 0.0]]], np.float32), 0.0, "linear")
    np.testing.assert_allclose(y[0, 0], [1.0, 0.735356983, 0.0], atol=2e-6)
    y = output_transform(np.array([[[1.0, 0.5, 0.25]]], np.float32), 0.0, "aces")
    np.testing.assert_allclose(y[0, 0, 0], srgb_encode(2.54 / 3.16), atol=2e-6)


@pytest.mark.parametrize("tonemap", ["aces", "linear"])
@pytest.mark.parametrize("exposure", [0.0, 1.5, -2.0])
def test_output_transform_matches_independent_formulas(tonemap, exposure):
    rng = np.random.default_rng(7)
    x = np.concatenate([np.zeros(4), np.geomspace(1e-5, 50.0, 400), rng.uniform(0, 2, 196)])
    x = x.reshape(20, 10, 3).astype(np.float32)
    got = output_transform(x, exposure, tonemap)
    assert got.shape == x.shape and got.dtype == np.float32
    scaled = x.astype(np.float64) * 2.0 ** exposure
    ref = srgb_encode(aces_narkowicz(scaled) if tonemap == "aces" else np.clip(scaled, 0, 1))
    # float32 evaluation of the same curve: measured max |diff| ~2e-7
    np.testing.assert_allclose(got, ref, atol=3e-6, rtol=0)
    assert got.min() >= 0.0 and got.max() <= 1.0


def test_output_transform_negative_and_unknown():
    y = output_transform(np.full((1, 1, 3), -1.0, np.float32), 0.0, "aces")
    assert (y == 0).all()
    from dermis.errors import DermisError

    with pytest.raises(DermisError, match="tonemap"):
        output_transform(np.zeros((1, 1, 3), np.float32), 0.0, "reinhard")


# ---------------------------------------------------------------------------------------------
# PNG and EXR round trips


def test_png_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    h, w = 5, 7
    k = rng.integers(0, 255, (h, w, 3))
    frac = rng.choice([0.2, 0.35, 0.65, 0.8], (h, w, 3))  # away from the .5 rounding boundary
    x = ((k + frac) / 255.0).astype(np.float32)
    x[0, 0] = [-0.5, 1.7, 1.0]  # out of range: clamped
    path = write_png(tmp_path / "a.png", x)
    assert path == tmp_path / "a.png"
    with Image.open(tmp_path / "a.png") as im:
        assert im.format == "PNG" and im.size == (w, h) and im.mode == "RGB"
        got = np.asarray(im)
    expected = np.where(frac < 0.5, k, k + 1)
    expected[0, 0] = [0, 255, 255]
    np.testing.assert_array_equal(got, expected)
    assert folder_names(tmp_path) == ["a.png"]


@pytest.mark.parametrize("half", [False, True])
def test_exr_round_trip(tmp_path, half):
    rng = np.random.default_rng(4)
    h, w = 6, 9
    x = (rng.standard_normal((h, w, 3)) * 10.0).astype(np.float32)  # HDR and negative values survive
    x[0, 0] = [1e4, 1e-3, 0.0]
    write_exr(tmp_path / "a.exr", x, half=half)
    (ww, hh), ch = read_exr(tmp_path / "a.exr")
    assert (ww, hh) == (w, h)
    got = ch["RGB"] if "RGB" in ch else np.stack([ch["R"], ch["G"], ch["B"]], -1)
    assert got.shape == (h, w, 3)
    assert got.dtype == (np.float16 if half else np.float32)
    expected = x.astype(np.float16) if half else x
    np.testing.assert_array_equal(got, expected)
    assert folder_names(tmp_path) == ["a.exr"]


# ---------------------------------------------------------------------------------------------
# atomic writes


class Boom(RuntimeError):
    pass


def test_png_write_failure_leaves_nothing(tmp_path, monkeypatch):
    def failing_save(self, fp, *a, **k):
        with open(fp, "wb") as f:
            f.write(b"\x89PNG\r\n\x1a\n half a file")
        raise Boom("encoder died")

    monkeypatch.setattr(Image.Image, "save", failing_save)
    with pytest.raises(Boom):
        write_png(tmp_path / "out.png", np.zeros((4, 4, 3), np.float32))
    assert folder_names(tmp_path) == []


def test_png_write_failure_keeps_the_previous_file(tmp_path, monkeypatch):
    write_png(tmp_path / "out.png", np.full((4, 4, 3), 0.5, np.float32))
    before = (tmp_path / "out.png").read_bytes()

    def failing_save(self, fp, *a, **k):
        with open(fp, "wb") as f:
            f.write(b"garbage")
        raise Boom("encoder died")

    monkeypatch.setattr(Image.Image, "save", failing_save)
    with pytest.raises(Boom):
        write_png(tmp_path / "out.png", np.zeros((4, 4, 3), np.float32))
    assert (tmp_path / "out.png").read_bytes() == before
    assert folder_names(tmp_path) == ["out.png"]


def test_exr_write_failure_leaves_nothing(tmp_path, monkeypatch):
    class FailingFile:
        def __init__(self, *a, **k):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, path):
            with open(path, "wb") as f:
                f.write(b"v/1\x01 partial")
            raise Boom("disk full")

    monkeypatch.setattr(OpenEXR, "File", FailingFile)
    with pytest.raises(Boom):
        write_exr(tmp_path / "out.exr", np.zeros((4, 4, 3), np.float32))
    assert folder_names(tmp_path) == []


def test_write_into_missing_folder_is_a_user_error(tmp_path):
    from dermis.errors import DermisError

    with pytest.raises(DermisError, match="does not exist"):
        write_png(tmp_path / "nope" / "a.png", np.zeros((2, 2, 3), np.float32))
    assert folder_names(tmp_path) == []


def test_outputs_get_the_usual_permissions(tmp_path):
    """Atomic writes go through mkstemp (mode 0600); the final file follows the umask instead."""
    import os
    import stat

    from dermis.images import write_png

    old = os.umask(0o022)
    try:
        p = write_png(tmp_path / "a.png", np.zeros((4, 4, 3), np.float32))
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == 0o644
