"""python -m dermis.subsurface_transfer SCENE.toml [--walks N] [--grid N] [--taps N] [--thin-mm MM] [--near-mm MM] [--out DIR]:
bake the scene's mesh (dermis.subsurface_transfer.store.bake_scene) and print where it was written."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from dermis.errors import DermisError
from dermis.subsurface_transfer import bake as B


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dermis.subsurface_transfer", description=__doc__.split(":")[1])
    ap.add_argument("scene")
    ap.add_argument("--walks", type=int, default=B.DEFAULT_WALKS)
    ap.add_argument("--grid", type=int, default=B.DEFAULT_GRID)
    ap.add_argument("--taps", type=int, default=B.DEFAULT_TAPS)
    ap.add_argument("--thin-mm", type=float, default=B.THIN_MM)
    ap.add_argument("--near-mm", type=float, default=B.NEAR_MM)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(argv)
    try:
        if a.walks < 1 or a.taps < 2 or a.grid < 16 or not a.thin_mm > 0 or not a.near_mm >= 0:
            raise DermisError("--walks must be >= 1, --taps >= 2, --grid >= 16, --thin-mm > 0 and --near-mm >= 0")
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
