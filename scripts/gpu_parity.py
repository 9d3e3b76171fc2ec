#!/usr/bin/env python3
"""Render the example and reference scenes with every technique and save the linear radiance.

Run on two machines (an NVIDIA GPU and Mesa llvmpipe) and compare the two files with
``scripts/gpu_parity.py compare A.npz B.npz``: the same code must give the same picture on both
(issue 14: "the same code must run on NVIDIA GPUs"). Differences come from MSAA sample patterns,
texture filtering precision and transcendental functions, so they are measured in FLIP, not bits.

    scripts/gpu_parity.py render OUT.npz [--size 512]
    scripts/gpu_parity.py compare A.npz B.npz
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
SCENES = ["examples/lee-perry-smith.toml"] + [f"examples/reference/{n}.toml" for n in ("front-key", "side", "back-ears", "environment")]
TECHNIQUES = ["tsd", "ssss", "preintegrated", "lambert"]


def render_all(out: Path, size: int, samples: int | None) -> None:
    sys.path.insert(0, str(REPO / "src"))
    import dermis
    from dermis.renderer import Renderer

    arrays, meta = {}, {"size": size, "scenes": {}}
    for path in SCENES:
        scene = dermis.load_scene(REPO / path)
        name = Path(path).stem
        opts = {} if samples is None else {"samples": samples}
        t0 = time.perf_counter()
        with Renderer(scene, (size, size), **opts) as r:
            meta["renderer"] = r.info["renderer"]
            meta["scenes"][name] = {"setup_s": round(time.perf_counter() - t0, 3), "frame_ms": {}}
            for tech in TECHNIQUES:
                img = r.render(tech)
                meta["scenes"][name]["frame_ms"][tech] = round(r.stats["frame_ms"], 2)
                arrays[f"{name}/{tech}"] = img.astype(np.float32)
        print(f"{name}: {meta['scenes'][name]}", flush=True)
    np.savez_compressed(out, meta=json.dumps(meta), **arrays)


def compare(a: Path, b: Path) -> None:
    sys.path.insert(0, str(REPO / "src"))
    import dermis
    import flip_evaluator as flip
    from dermis.reference.validate import display

    scenes = {Path(p).stem: dermis.load_scene(REPO / p) for p in SCENES}
    A, B = np.load(a), np.load(b)
    ma, mb = json.loads(str(A["meta"])), json.loads(str(B["meta"]))
    print(f"A: {ma.get('renderer')}   B: {mb.get('renderer')}")
    print(f"{'scene/technique':34s} {'FLIP':>7s} {'rel.mean R,G,B':>24s} {'p99 |d|/max':>12s}")
    for key in sorted(k for k in A.files if k != "meta"):
        if key not in B.files:
            continue
        x, y = A[key], B[key]
        sc = scenes[key.split("/")[0]]
        fmap, _, _ = flip.evaluate(np.ascontiguousarray(display(sc, y), np.float32),
                                   np.ascontiguousarray(display(sc, x), np.float32), "LDR", applyMagma=False)
        f = float(np.mean(fmap))
        rel = (x.reshape(-1, 3).mean(0) / np.maximum(y.reshape(-1, 3).mean(0), 1e-9))
        d = np.abs(x - y).max(-1)
        p99 = float(np.percentile(d, 99) / max(float(y.max()), 1e-9))
        print(f"{key:34s} {f:7.4f} {' '.join(f'{v:7.4f}' for v in rel):>24s} {p99:12.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render")
    r.add_argument("out", type=Path)
    r.add_argument("--size", type=int, default=512)
    r.add_argument("--samples", type=int, default=None)
    c = sub.add_parser("compare")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    args = ap.parse_args()
    if args.cmd == "render":
        render_all(args.out, args.size, args.samples)
    else:
        compare(args.a, args.b)


if __name__ == "__main__":
    main()
