"""`dermis bench`: the floors it measures beside each pass, and the table it writes.

Timings are never asserted (the machines are shared); what is checked is that every floor is
measured, that the pass -> floor mapping covers the passes the techniques report, and that the
ratios in the table are the pass times divided by those floors."""

from __future__ import annotations

import math

import numpy as np

import dermis
from dermis.bench import floor_ratios, markdown_table, run_bench


def test_floors_and_ratios_on_a_small_scene(box_toml):
    scene = dermis.load_scene(box_toml)
    info, results = run_bench(scene, ["lambert", "tsd", "ssss"], size=(64, 64), irradiance_size=128, frames=1,
                              pipelined_frames=2)
    floors = info["floors_ms"]
    assert set(floors) == {"copy", "copy_screen", "uv_raster", "uv_raster_half", "screen_raster", "depth_only"}
    assert all(math.isfinite(v) and v > 0 for v in floors.values())
    tsd = floor_ratios(results["tsd"]["lights"]["passes_ms"], floors, scene.profile.k)
    # every timed pass of tsd except the cheap resolve/stretch bookkeeping has a floor
    assert {"shadow", "tsd_irradiance", "tsd_blur", "tsd_translucency", "tsd_final"} <= set(tsd)
    ms, floor, multiple = tsd["tsd_blur"]
    assert floor == 2 * scene.profile.k * floors["copy"]
    assert multiple == ms / floor
    assert floor_ratios(results["ssss"]["lights"]["passes_ms"], floors, scene.profile.k)["ssss_blur"][1] == \
        2 * scene.profile.k * floors["copy_screen"]
    table = markdown_table(info, results, (64, 64), 128, scene.profile.k)
    assert "| tsd | tsd_blur |" in table and f"{multiple:.2f}x" in table
    # pipelined frames: every technique and workload, positive, and on llvmpipe the rasteriser's
    # busy time per frame within the wall time per frame (it cannot be busier than the wall clock)
    for name, res in results.items():
        for mode in ("lights", "camera"):
            p = res["pipelined"][mode]
            assert p["frames"] == 2
            assert all(math.isfinite(p[k]) and p[k] > 0 for k in ("gpu_ms", "throughput_ms", "readback_ms")), (name, mode, p)
            if info["software"]:
                assert p["gpu_clock"] == "llvmpipe rasteriser threads"
                assert p["gpu_ms"] <= 1.1 * p["throughput_ms"], (name, mode, p)
        piped_table = table.split("Pipelined frames")[1].split("Floors")[0]
        cells = [c.strip() for c in next(l for l in piped_table.splitlines() if l.startswith(f"| {name} | ")).split("|")[1:-1]]
        assert cells[1:] == [f"{res['pipelined'][m][k]:.2f}" for m in ("lights", "camera")
                             for k in ("gpu_ms", "throughput_ms")] + [f"{res['pipelined']['lights']['readback_ms']:.2f}"]


def test_a_frame_rendered_without_readback_reads_back_as_render_returns_it(box_toml):
    from dermis.renderer import Renderer

    scene = dermis.load_scene(box_toml)
    with Renderer(scene, (48, 32), irradiance_size=64, shadow_size=256) as r:
        assert r.render("tsd", readback=False) is None
        rgb, rgba = r.read_frame(), r.read_frame(with_alpha=True)
        assert rgb.shape == (32, 48, 3) and rgba.shape == (32, 48, 4) and rgb.flags.c_contiguous
        assert np.array_equal(rgba[:, :, :3], rgb)
        assert np.array_equal(r.render("tsd"), rgb)
        assert np.array_equal(r.render("tsd", with_alpha=True), rgba)
        assert 0.0 < rgba[:, :, 3].mean() < 1.0  # the box covers part of the frame: alpha is its coverage
