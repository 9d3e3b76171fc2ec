"""python -m dermis.subsurface_transfer SCENE.toml [--walks N] [--grid N] [--taps N] [--thin-mm MM] [--near-mm MM] [--out DIR]:
bake the scene's mesh (dermis.subsurface_transfer.store.bake_scene) and print where it was written."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from dermis.errors import DermisError


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dermis.subsurface_transfer", description=__doc__.split(":")[1])
    ap.add_argument("scene")
    ap.add_argument("--walks", type=int, default=192)
    ap.add_argument("--grid", type=int, default=512)
    ap.add_argument("--taps", type=int, default=8)
    ap.add_argument("--thin-mm", type=float, default=10.0)
    ap.add_argument("--near-mm", type=float, default=6.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(argv)
    try:
        import dermis
        from dermis.subsurface_transfer.store import bake_scene

        sc = dermis.load_scene(a.scene)
        t0 = time.perf_counter()
        p = bake_scene(sc, a.out, progress=lambda s: print(f"{time.perf_counter() - t0:7.1f} s {s}", flush=True),
                       walks=a.walks, grid=a.grid, taps=a.taps, thin_mm=a.thin_mm, near_mm=a.near_mm, seed=a.seed)
    except DermisError as e:
        print(f"dermis: error: {e}", file=sys.stderr)
        return 2
    print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
