"""tsd's irradiance pass as `dermis bench` times it (``tsd_irradiance`` of a lights-moving frame:
the texture-space raster and the dilation), this tree's shader against another revision's in the
SAME Renderer, frames interleaved (the lights turn a little before each frame, as in bench).

    PYTHONPATH=src python benchmarks/tsd_irradiance_ab.py [--against main] [--frames 4]

Prints the per-frame ``tsd_irradiance`` and frame wall ms of each; the load average beside them.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import dermis  # noqa: E402
from dermis.bench import HEAD_TOML, _rotate  # noqa: E402
from dermis.gl.shaders import load_shader_source  # noqa: E402
from dermis.renderer import Renderer  # noqa: E402
from dermis.techniques.shared import MAX_GAUSSIANS  # noqa: E402
from pass_breakdown import source_at  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--against", default="main")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--irradiance-size", type=int, default=1024)
    a = ap.parse_args(argv)
    sc = dermis.load_scene(str(HEAD_TOML))
    with Renderer(sc, (a.size, a.size), irradiance_size=a.irradiance_size) as r:
        r.render("tsd")
        t = r.technique("tsd")
        mine = t._irradiance_programs(len(sc.lights))  # the program render() draws for the head's 3 lights
        d = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
        other = r.ctx.program(vertex_shader=load_shader_source("tsd/uv_space.vert", d),
                              fragment_shader=source_at(a.against, "tsd/irradiance.frag", d))
        base = [tuple(L.direction) for L in sc.lights]
        res = {"this tree": [], f"@{a.against}": []}
        f = 0
        try:
            for _ in range(a.frames):
                for name, p in zip(res, (mine, other)):
                    t.p_irradiance = p  # the same targets: the other shader leaves the sharp-shadow target unwritten
                    f += 1
                    for L, dd in zip(sc.lights, base):
                        L.direction = _rotate(dd, 0.02 * f)
                    r.render("tsd")
                    res[name].append((r.stats["passes_ms"]["tsd_irradiance"], r.stats["frame_ms"]))
        finally:
            t.p_irradiance = None  # back to the program per light count
            other.release()
    print(f"load {os.getloadavg()[0]:.1f}")
    for k, v in res.items():
        print(f"{k}: tsd_irradiance median {statistics.median(x for x, _ in v):.0f} ms "
              f"({', '.join(f'{x:.0f}' for x, _ in v)}); frame median {statistics.median(y for _, y in v):.0f} ms")


if __name__ == "__main__":
    main()
