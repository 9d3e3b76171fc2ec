"""`dermis bench`: the floors it measures beside each pass, and the table it writes.

Timings are never asserted (the machines are shared); what is checked is that every floor is
measured, that the pass -> floor mapping covers the passes the techniques report, and that the
ratios in the table are the pass times divided by those floors."""

from __future__ import annotations

import math
import statistics

import numpy as np

import dermis
from dermis.bench import FLOOR_REPEATS, floor_ratios, markdown_table, run_bench
from dermis.bench_floors import FloorSampler, floor_summary, stable_floors


def test_floors_and_ratios_on_a_small_scene(box_toml):
    scene = dermis.load_scene(box_toml)
    info, results = run_bench(scene, ["lambert", "tsd", "ssss"], size=(64, 64), irradiance_size=128, frames=1,
                              pipelined_frames=2)
    floors = info["floors_ms"]
    assert set(floors) == {"copy", "copy_screen", "uv_raster", "uv_raster_half", "screen_raster", "depth_only"}
    assert all(math.isfinite(v) and v > 0 for v in floors.values())
    # the floors are sampled before the first technique, after each of the 3 x 2 workloads and after
    # each of their frames (1 here), and the divisor is each floor's minimum sample, its spread reported
    samples, spread = info["floor_samples_ms"], info["floors_spread"]
    assert {k: len(v) for k, v in samples.items()} == {k: FLOOR_REPEATS * (1 + 3 * 2) + 3 * 2 * 1 for k in floors}
    for k, v in samples.items():
        assert floors[k] == min(v)
        assert spread[k] == {"min": min(v), "median": statistics.median(v), "max": max(v), "n": len(v),
                             "spread": max(v) / min(v)}
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
    # beside it the pass's fastest frame over the same floor (one frame here: its minimum is its median)
    fastest = floor_ratios(results["tsd"]["lights"]["passes_min_ms"], floors, scene.profile.k)["tsd_blur"]
    assert fastest == (ms, floor, multiple)
    row = next(l for l in table.splitlines() if l.startswith("| tsd | tsd_blur |"))
    assert f"| {multiple:.2f}x | {fastest[0]:.1f} | {fastest[2]:.2f}x |" in row, row
    if info["software"]:
        # llvmpipe: every timed pass and floor sample also on the CPU-time clock, the divisor its minimum
        cpu_samples = info["floor_samples_cpu_ms"]
        assert {k: len(v) for k, v in cpu_samples.items()} == {k: len(v) for k, v in samples.items()}
        assert info["floors_cpu_ms"] == {k: min(v) for k, v in cpu_samples.items()}
        assert all(v > 0 for v in info["floors_cpu_ms"].values())
        cpu_passes = results["tsd"]["lights"]["passes_cpu_ms"]
        assert set(cpu_passes) == set(results["tsd"]["lights"]["passes_ms"]) and all(v > 0 for v in cpu_passes.values())
        c = floor_ratios(cpu_passes, info["floors_cpu_ms"], scene.profile.k)["tsd_blur"]
        assert c[1] == 2 * scene.profile.k * info["floors_cpu_ms"]["copy"]
        assert row.endswith(f"| {c[0]:.1f} | {c[1]:.1f} | {c[2]:.2f}x |"), row
    s = spread["copy"]
    assert f"copy {floors['copy']:.2f} [{s['median']:.2f}, {s['max']:.2f}, n={s['n']}]" in table
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


def test_the_divisor_is_each_floors_minimum_and_the_spread_is_reported():
    """The reporting logic on made-up samples (ms): a floor disturbed by load in some samples still
    divides by its undisturbed (minimum) cost, so the multiple does not shrink under load; a floor of
    0 (no shadowed light) has no spread and no ratio."""
    samples = {"copy": [4.0, 1.0, 9.0, 1.5], "uv_raster": [2.0, 2.0, 2.0], "depth_only": [0.0, 0.0]}
    assert stable_floors(samples) == {"copy": 1.0, "uv_raster": 2.0, "depth_only": 0.0}
    summary = floor_summary(samples)
    assert summary["copy"] == {"min": 1.0, "median": 2.75, "max": 9.0, "n": 4, "spread": 9.0}
    assert summary["uv_raster"]["spread"] == 1.0 and summary["depth_only"]["spread"] is None
    floors = {**stable_floors(samples), "copy_screen": 1.0, "uv_raster_half": 1.0, "screen_raster": 1.0}
    ratios = floor_ratios({"tsd_blur": 24.0, "tsd_irradiance": 9.0, "shadow": 5.0}, floors, gaussians=6)
    assert ratios["tsd_blur"] == (24.0, 12.0, 2.0)  # 2 x 6 Gaussians x copy's minimum (1.0), not its median
    assert ratios["tsd_irradiance"] == (9.0, 3.0, 3.0)  # uv_raster + copy
    assert "shadow" not in ratios


def test_sampling_the_floors_between_frames_leaves_the_frame_unchanged(box_toml):
    """run_bench samples the floors between a technique's frames: the floors' own targets and state
    must not leak into the renderer's next frame."""
    from dermis.renderer import Renderer

    scene = dermis.load_scene(box_toml)
    with Renderer(scene, (48, 32), irradiance_size=64, shadow_size=256) as r:
        before = {name: r.render(name) for name in ("lambert", "tsd")}
        with FloorSampler(r, 64) as fs:
            for name in ("lambert", "tsd"):
                r.invalidate()
                fs.sample(1)
                assert np.array_equal(r.render(name), before[name]), name
        assert all(len(v) == 2 for v in fs.samples_ms.values())


def test_the_cpu_clock_counts_work_not_waiting():
    """dermis.gl.context.cpu_busy_ns (bench's CPU-time clock on llvmpipe) advances with the calling
    thread's work and not while it waits (as it does not while another process holds the core)."""
    import time

    from dermis.gl.context import cpu_busy_ns

    c0 = cpu_busy_ns()
    time.sleep(0.2)
    slept = (cpu_busy_ns() - c0) / 1e9
    c0, t0 = cpu_busy_ns(), time.thread_time()
    while time.thread_time() - t0 < 0.1:
        pass
    worked = (cpu_busy_ns() - c0) / 1e9
    assert slept < 0.05, slept
    assert worked >= 0.1, worked
