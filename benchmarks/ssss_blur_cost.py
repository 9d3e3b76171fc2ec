"""ssss's blur (the two screen-space passes) against its copy floor, this tree's shaders beside an
older revision's, in ONE process (so the ratio means something on a loaded machine).

    PYTHONPATH=src python benchmarks/ssss_blur_cost.py [--scene TOML] [--size 512] [--frames 7] [--before REV |
        --before-shaders DIR] [--option NAME=VALUE ...] [--json OUT]

The example head (examples/lee-perry-smith.toml; ``--scene``: another, e.g. examples/reference/front-key.toml,
whose head fills 73 % of the frame against the example's 50 %: the blur's cost follows the skin's pixels),
ssss, moving lights (every pass re-runs). ``--before`` swaps only the shaders: at square sizes only where the
packed images' layout differs (round 22 stores them transposed: pixel (x, y) at texel (y, x)).
Timed: ``ssss_blur`` per frame (GL_TIME_ELAPSED on a GPU, wall time around glFinish on llvmpipe),
median over ``--frames``, the two shader sets interleaved frame by frame; the floor is
``dermis.bench_floors``' copy_screen times 2K (one full-screen copy per Gaussian per pass, K = 6).
``--before REV``: the ssss shaders of git revision REV (``git show REV:src/dermis/shaders/ssss/F``);
``--before-shaders DIR``: a folder holding an older ssss/ (where there is no git, e.g. a GPU box).
``--option surface_measure=false``: ssss options for both (e.g. to compare like for like).
``--also NAME=VALUE``: one more set, this tree's shaders with that option changed (e.g.
``--also grain_filter=false``); options the older shaders do not have are left out for them.
Printed: ms and multiple of the floor for each, and how far this tree's IMAGE is from the older
one's: max |a - b| / max(|b|, 1e-3 * p99(b)) over the frame (linear, all channels).
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent


def old_shader_dir(rev: str | None, folder: str | None, into: Path) -> Path:
    """A copy of this tree's shader folder whose ssss/ holds the older revision's files."""
    import dermis.gl.shaders as shaders

    dest = into / "shaders"
    shutil.copytree(shaders.SHADER_DIR, dest)
    if folder:
        src = Path(folder)
        src = src / "ssss" if (src / "ssss").is_dir() else src
        for f in src.glob("*"):
            shutil.copy(f, dest / "ssss" / f.name)
    else:
        names = subprocess.run(["git", "-C", str(REPO), "ls-tree", "--name-only", f"{rev}:src/dermis/shaders/ssss"],
                               check=True, capture_output=True, text=True).stdout.split()
        for n in names:
            text = subprocess.run(["git", "-C", str(REPO), "show", f"{rev}:src/dermis/shaders/ssss/{n}"],
                                  check=True, capture_output=True, text=True).stdout
            (dest / "ssss" / n).write_text(text)
    return dest


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    floor = 1e-3 * float(np.percentile(np.abs(b), 99))
    return float((np.abs(a - b) / np.maximum(np.abs(b), floor)).max())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(REPO / "examples" / "lee-perry-smith.toml"))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--before", default=None, help="git revision whose ssss shaders to time beside this tree's")
    ap.add_argument("--before-shaders", default=None, help="a folder with the older ssss/ shaders")
    ap.add_argument("--option", action="append", default=[], help="ssss option NAME=VALUE (true/false/number)")
    ap.add_argument("--also", action="append", default=[], help="one more set: this tree with option NAME=VALUE")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)

    import dermis
    import dermis.gl.shaders as shaders
    from dermis.bench_floors import measure_floors
    from dermis.gl.context import create_context
    from dermis.renderer import Renderer

    sc = dermis.load_scene(a.scene)
    def parse(pairs):
        out = {}
        for o in pairs:
            key, _, value = o.partition("=")
            out[key] = {"true": True, "false": False}.get(value.lower(), None)
            if out[key] is None:
                out[key] = float(value) if "." in value else int(value)
        return out

    options = parse(a.option)
    size = (a.size, a.size)
    ctx = create_context()
    tmp = Path(tempfile.mkdtemp(prefix="ssss_cost_"))
    sets = {"this tree": (shaders.SHADER_DIR, options)}
    for o in a.also:
        sets[f"this tree, {o}"] = (shaders.SHADER_DIR, {**options, **parse([o])})
    if a.before or a.before_shaders:
        old = old_shader_dir(a.before, a.before_shaders, tmp)
        # options whose shaders the older tree lacks stay off there
        has_filter = "SSSS_GRAIN_FILTER" in (old / "ssss" / "kernel.glsl").read_text()
        old_options = {**options, **({} if has_filter else {"grain_filter": False})}
        sets[f"before ({a.before or a.before_shaders})"] = (old, old_options)
    renderers, times, images = {}, {}, {}
    try:
        for name, (folder, opts) in sets.items():
            shaders.SHADER_DIR = folder  # the programs are compiled on the first render
            r = renderers[name] = Renderer(sc, size, ctx=ctx, irradiance_size=1024)
            r.technique("ssss", **opts)
            images[name] = r.render("ssss").astype(np.float64)
            times[name] = []
        shaders.SHADER_DIR = sets["this tree"][0]
        first = next(iter(renderers.values()))
        floors = measure_floors(first, repeats=a.frames)
        floor = 2 * sc.profile.k * floors["copy_screen"]
        for _ in range(a.frames):
            for name, r in renderers.items():
                r.invalidate()  # as with moving lights: every pass re-runs
                r.render("ssss")
                times[name].append(r.stats["passes_ms"]["ssss_blur"])
        info = dict(first.info)
    finally:
        for r in renderers.values():
            r.release()
        shaders.SHADER_DIR = sets["this tree"][0]
        shutil.rmtree(tmp, ignore_errors=True)
    import os

    load = os.getloadavg()
    out = {"renderer": info.get("renderer"), "size": a.size, "frames": a.frames, "load_average": load, "options": options,
           "copy_screen_ms": floors["copy_screen"], "floor_ms": floor, "sets": {}}
    print(f"{info.get('renderer')}, {a.size}^2, load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}; "
          f"floor 2K x copy_screen = {floor:.2f} ms")
    ref = images["this tree"]
    for name in renderers:
        ms = statistics.median(times[name])
        entry = {"ssss_blur_ms": ms, "multiple_of_floor": ms / floor, "all_ms": times[name]}
        if name != "this tree":
            entry["max_relative_image_difference"] = relative_difference(ref, images[name])
        out["sets"][name] = entry
        extra = (f", image vs this tree: max relative difference {entry['max_relative_image_difference']:.2e}"
                 if "max_relative_image_difference" in entry else "")
        print(f"{name:28s} ssss_blur {ms:8.2f} ms = {ms / floor:6.2f}x the floor{extra}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
