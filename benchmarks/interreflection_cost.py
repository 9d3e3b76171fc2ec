"""Cost of the one diffuse bounce (dermis.geometry.interreflection) on the head.

    PYTHONPATH=src python benchmarks/interreflection_cost.py [--scene examples/reference/side.toml]
        [--irradiance 1024] [--frames 6] [--rays N] [--shared [--size 512]] [--orders-ab]

Prints: the bake's time uncached (Embree, CPU) and read back from the disk cache; then, in ONE
Renderer, per frame whose lights changed (so every texture-space pass reruns), the times of
tsd_irradiance (the lights' irradiance pass and the gutter dilation) and tsd_interreflection (rho E,
its reductions, the per-vertex gather and the splat), as medians over the frames, and the load
average. On Mesa's llvmpipe the pass timer is wall time around glFinish (dermis.techniques.base.PassTimer).

``--shared``: the bounce ssss, preintegrated and lambert share (dermis.gl.interreflection.SharedBounce):
per technique, in one Renderer, frames with the bounce on and off alternated back to back: frames
whose lights changed (the shared pass "interreflection" reruns; its time and the frame's) and
camera-only frames (the bounce is only read), medians over the frames of the sum of the frame's timed passes.

``--orders-ab``: the higher bounces' cost (dermis.gl.interreflection.BounceSeries): in one Renderer,
frames whose lights changed with the one bounce alone (BOUNCE_ORDERS = 1: main's passes) and with
every order (BOUNCE_ORDERS, 4) alternated back to back, tsd's tsd_interreflection and the shared
bounce's "interreflection" (drawn for lambert), medians over the frames.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default=str(REPO / "examples" / "reference" / "side.toml"))
    ap.add_argument("--irradiance", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--rays", type=int, default=None)
    ap.add_argument("--shared", action="store_true", help="the shared bounce of ssss, preintegrated, lambert")
    ap.add_argument("--size", type=int, default=512, help="frame size of --shared")
    ap.add_argument("--orders-ab", action="store_true", help="one bounce vs every order, alternated")
    a = ap.parse_args()
    if a.shared:
        return shared(a)
    if a.orders_ab:
        return orders_ab(a)
    import dermis
    from dermis.geometry import interreflection
    from dermis.renderer import Renderer

    if a.rays:
        interreflection.BAKE_RAYS = a.rays
    print(f"load average before: {os.getloadavg()}")
    sc = dermis.load_scene(a.scene)
    m = sc.mesh
    with tempfile.TemporaryDirectory() as cache:
        os.environ["DERMIS_CACHE_DIR"] = cache
        h = interreflection.bake_vertex_hits(m.positions, m.normals, m.indices)
        interreflection._MEMORY.clear()
        t0 = time.perf_counter()
        cached = interreflection.bake_vertex_hits(m.positions, m.normals, m.indices)
        t_disk = time.perf_counter() - t0
        print(f"bake: {len(m.positions)} vertices x {h.rays} rays: {h.seconds:.2f} s uncached; "
              f"{t_disk * 1e3:.1f} ms from the disk cache (cached={cached.cached}); "
              f"{(h.triangle >= 0).mean():.3f} of the rays hit the skin")
        with Renderer(sc, (256, 256), irradiance_size=a.irradiance) as r:
            r.render("tsd")
            irr, bounce = [], []
            for i in range(a.frames):
                sc.lights[0].intensity *= 1.0 + 1e-3 * (1 if i % 2 else -1)  # lights changed: texture space reruns
                r.timer.reset()
                r.render("tsd")
                ms = r.stats["passes_ms"]
                irr.append(ms["tsd_irradiance"])
                bounce.append(ms["tsd_interreflection"])
            tsd = r.technique("tsd")
            mi, mb = statistics.median(irr), statistics.median(bounce)
            print(f"irradiance {a.irradiance}^2, gather level {tsd.bounce_level}, {r.info['renderer']}: "
                  f"tsd_irradiance {mi:.1f} ms, tsd_interreflection {mb:.1f} ms (ratio {mb / mi:.2f}), "
                  f"medians of {a.frames} frames")
    print(f"load average after: {os.getloadavg()}")


def shared(a):
    import dermis
    from dermis.renderer import Renderer

    med = statistics.median
    print(f"load average before: {os.getloadavg()}")
    sc = dermis.load_scene(a.scene)
    pos0 = tuple(sc.camera.position)
    with Renderer(sc, (a.size, a.size), irradiance_size=a.irradiance) as r:
        for t in ("ssss", "preintegrated", "lambert"):
            for on in (True, False):  # compile both programs, bake, warm up
                sc.interreflection = on
                r.render(t)
            light = {True: [], False: []}
            cam = {True: [], False: []}
            bounce = []
            for i in range(a.frames):
                for on in (True, False):
                    sc.interreflection = on
                    sc.lights[0].intensity *= 1.0 + 1e-3 * (1 if i % 2 else -1)  # the lights changed
                    r.render(t)
                    light[on].append(sum(r.stats["passes_ms"].values()))
                    if on:
                        assert "interreflection" in r.stats["passes_run"]
                        bounce.append(r.stats["passes_ms"]["interreflection"])
                sc.interreflection = True
                r.render(t)  # the bounce of the lights as they are now (the off frame changed them)
                for on in (True, False):
                    sc.interreflection = on
                    sc.camera.position = tuple(p + 1e-3 * (i % 2 + on) for p in pos0)  # the camera only
                    r.render(t)
                    cam[on].append(sum(r.stats["passes_ms"].values()))
                    assert "interreflection" not in r.stats["passes_run"]
            print(f"{t}: lights changed: passes {med(light[False]):.1f} -> {med(light[True]):.1f} ms with the bounce "
                  f"(its pass {med(bounce):.1f} ms, gather level {r.interreflection.level}); camera only: passes "
                  f"{med(cam[False]):.1f} -> {med(cam[True]):.1f} ms; medians of {a.frames} ({a.size}^2, "
                  f"irradiance {a.irradiance}^2, {r.info['renderer']})")
    print(f"load average after: {os.getloadavg()}")


def orders_ab(a):
    import dermis
    from dermis.geometry import interreflection
    from dermis.renderer import Renderer

    med = statistics.median
    every = interreflection.BOUNCE_ORDERS
    print(f"load average before: {os.getloadavg()}")
    sc = dermis.load_scene(a.scene)
    with Renderer(sc, (256, 256), irradiance_size=a.irradiance) as r:
        for t, pass_name in (("tsd", "tsd_interreflection"), ("lambert", "interreflection")):
            ms = {1: [], every: []}
            frame = {1: [], every: []}
            for n in (1, every):  # compile, bake, warm up
                interreflection.BOUNCE_ORDERS = n
                r.render(t)
            for i in range(a.frames):
                for n in ((1, every) if i % 2 else (every, 1)):
                    interreflection.BOUNCE_ORDERS = n
                    sc.lights[0].intensity *= 1.0 + 1e-3 * (1 if i % 2 else -1)  # the lights changed
                    r.timer.reset()
                    r.render(t)
                    assert pass_name in r.stats["passes_run"]
                    ms[n].append(r.stats["passes_ms"][pass_name])
                    frame[n].append(sum(r.stats["passes_ms"].values()))
            level = r.technique("tsd").bounce_level if t == "tsd" else r.interreflection.level
            print(f"{t}: {pass_name} {med(ms[1]):.1f} ms (one bounce) -> {med(ms[every]):.1f} ms ({every} orders), "
                  f"min {min(ms[1]):.1f} -> {min(ms[every]):.1f}; the frame's passes {med(frame[1]):.0f} -> "
                  f"{med(frame[every]):.0f} ms (min {min(frame[1]):.0f} -> {min(frame[every]):.0f}); gather level {level}, medians of {a.frames} "
                  f"alternated frames (irradiance {a.irradiance}^2, {r.info['renderer']})")
    interreflection.BOUNCE_ORDERS = every
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
