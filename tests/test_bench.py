"""`dermis bench`: the floors it measures beside each pass, and the table it writes.

Timings are never asserted (the machines are shared); what is checked is that every floor is
measured, that the pass -> floor mapping covers the passes the techniques report, and that the
ratios in the table are the pass times divided by those floors."""

from __future__ import annotations

import math

import dermis
from dermis.bench import floor_ratios, markdown_table, run_bench


def test_floors_and_ratios_on_a_small_scene(box_toml):
    scene = dermis.load_scene(box_toml)
    info, results = run_bench(scene, ["lambert", "tsd", "ssss"], size=(64, 64), irradiance_size=128, frames=1)
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
