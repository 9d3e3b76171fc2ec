"""``dermis bench --viewer``: the viewer's frame rates in a scripted session on the real window.

The session drives the same entry points as the mouse (see viewer/script.py): ``orbit_frames``
frames of orbiting, then frames without input until the full frame is drawn, then
``light_frames`` frames of dragging the key light, then again until the full frame. Reported:
frames per second while orbiting and while dragging the light (median frame time, the whole
frame: events, render, upload, panel, swap), the output scale the progressive renderer settled
on, and the time of the refining full frame after each drag (on an interactive session the
refine starts REFINE_AFTER_S after the last input: that delay is added to "full quality after").
"""

from __future__ import annotations

import statistics


def _segment(report, frames):
    ms = [report["frame_ms"][f] for f in frames]
    return {"frames": len(ms), "median_ms": statistics.median(ms), "fps": 1e3 / statistics.median(ms),
            "quality": sorted(set(report["quality"][f] for f in frames))}


def viewer_bench(scene, size=(960, 640), *, orbit_frames: int = 30, light_frames: int = 12,
                 irradiance_size: int | None = None, samples: int = 4, progressive: bool = True,
                 show_gui: bool = True) -> dict:
    from dermis.viewer.app import Viewer
    from dermis.viewer.progressive import REFINE_AFTER_S
    from dermis.viewer.script import Script

    actions = []
    f = 1  # frame 0: the first full frame
    orbit = list(range(f, f + orbit_frames))
    actions += [{"frame": i, "orbit": [6, 0]} for i in orbit]
    f += orbit_frames
    refine_orbit = f          # no input: the full frame of the orbited view
    f += 2
    light = list(range(f, f + light_frames))
    actions += [{"frame": i, "light_drag": [8, 0]} for i in light]
    f += light_frames
    refine_light = f
    total = f + 2
    script = Script.from_dict({"actions": actions, "quit_after": total}, "viewer bench")
    with Viewer(scene, size, irradiance_size=irradiance_size, samples=samples, script=script, show_gui=show_gui,
                progressive=progressive) as v:
        report = v.run()
        renderer = v.renderer.info.get("renderer")
        sizes = (v.renderer.irradiance_size, v.renderer.shadows.tile_size)
    # the first two frames of each drag warm up (the interactive renderer is created, the scale adapts)
    out = {"renderer": renderer, "size": list(size), "progressive": progressive,
           "irradiance_size": sizes[0], "shadow_size": sizes[1],
           "orbit": _segment(report, orbit[2:]), "light_drag": _segment(report, light[2:]),
           # without progressive rendering every frame is the full one: its time is the wait.
           # Progressive: a mouse drag (orbit, light drag) ends with the button's release, after which
           # the viewer refines at once (ProgressiveRenderer.input_released): the wait is the refine
           # frame; keys and panel sliders have no release, so there it is REFINE_AFTER_S longer.
           "full_after_orbit_ms": report["frame_ms"][refine_orbit] if progressive
           else statistics.median(report["frame_ms"][f] for f in orbit[2:]),
           "full_after_light_ms": report["frame_ms"][refine_light] if progressive
           else statistics.median(report["frame_ms"][f] for f in light[2:]),
           "refine_wait_after_keys_ms": REFINE_AFTER_S * 1e3 if progressive else 0.0,
           "refine_quality": [report["quality"][refine_orbit], report["quality"][refine_light]]}
    return out
