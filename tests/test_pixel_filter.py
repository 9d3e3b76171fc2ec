"""Cycles' pixel filter as dermis.blender.pixel_filter reproduces it (no bpy needed): the window's
closed-form values, and a supersampled step edge against the filter integrated by quadrature."""
import numpy as np
import pytest
from scipy.integrate import quad

from dermis.blender.pixel_filter import blackman_harris, reconstruct
from dermis.errors import DermisError

A = (0.35875, 0.48829, 0.14128, 0.01168)  # the four-term Blackman-Harris coefficients (Harris 1978)


def test_window_closed_form_values():
    # Cycles doubles the width for Blackman-Harris (film.cpp filter_table): at filter_size 1.5 the
    # window spans +-1.5 px. Centre: a0 + a1 + a2 + a3 = 1; ends: a0 - a1 + a2 - a3; outside: 0
    assert blackman_harris(0.0) == pytest.approx(sum(A), abs=1e-12)
    assert blackman_harris(1.4999999) == pytest.approx(A[0] - A[1] + A[2] - A[3], abs=1e-6)
    assert blackman_harris(1.51) == 0.0 and blackman_harris(-2.0) == 0.0
    assert blackman_harris(0.75) == pytest.approx(A[0] - A[2], abs=1e-12)  # quarter period: cos terms 0, -1, 0
    assert blackman_harris(0.3) == pytest.approx(blackman_harris(-0.3), abs=1e-15)


def test_constant_and_identity():
    img = np.full((32, 24, 3), 0.37, np.float32)
    assert np.allclose(reconstruct(img, 4), 0.37, atol=1e-6)
    # factor 1: each pixel keeps the filter's weight at 0 and gives its neighbours the weight at 1 px
    x = np.zeros((9, 9, 1), np.float32)
    x[4, 4] = 1.0
    y = reconstruct(x, 1)[..., 0]
    w0, w1 = blackman_harris(0.0), blackman_harris(1.0)
    assert y[4, 4] == pytest.approx((w0 / (w0 + 2 * w1)) ** 2, rel=1e-5)
    assert y[4, 5] == pytest.approx(w0 * w1 / (w0 + 2 * w1) ** 2, rel=1e-5)


@pytest.mark.parametrize("edge", [3.25, 3.5, 3.875])  # on sample boundaries (1/16 px)
def test_step_edge_against_quadrature(edge):
    """A vertical step at film position ``edge`` (output pixels), drawn at 16 samples per pixel:
    each output pixel equals the filter-weighted fraction of its footprint past the edge."""
    k, n = 16, 8
    xs = (np.arange(n * k) + 0.5) / k
    img = np.repeat((xs >= edge).astype(np.float32)[None, :, None], n * k, axis=0)
    out = reconstruct(img, k)[n // 2, :, 0]
    norm = quad(blackman_harris, -1.5, 1.5)[0]
    for j in range(n):
        c = j + 0.5
        lo = max(edge - c, -1.5)
        want = quad(blackman_harris, lo, 1.5)[0] / norm if lo < 1.5 else 0.0
        assert out[j] == pytest.approx(want, abs=0.01), (j, out[j], want)
    # the ramp really spans neighbours: a box filter (dermis's own pixel) would give 0 or 1 there
    assert 0.02 < out[int(edge - 0.5)] < 0.98 or 0.02 < out[int(edge + 0.5)] < 0.98


def test_bad_shapes_are_refused():
    with pytest.raises(DermisError, match="times an output size"):
        reconstruct(np.zeros((10, 12, 3)), 4)


def test_cli_refuses_a_bad_supersample(tmp_path, capsys):
    from pathlib import Path

    from dermis.cli import main

    scene = Path(__file__).resolve().parent.parent / "examples" / "reference" / "side.toml"
    with pytest.raises(SystemExit) as e:
        main(["validate", "--against", "cycles", "--supersample", "0", str(scene), "--images", str(tmp_path / "v")])
    assert e.value.code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "dermis: error: --supersample: 0 is not an integer from 1 to 16"]
