"""dermis's light transport without subsurface scattering against Cycles' (issue 12, round 13).

lambert (dermis's shading with no subsurface scattering: the lights, the soft shadows, the occluded
environment, the skin-to-skin bounce light) against the converged Cycles render of the same scene
WITHOUT subsurface scattering (validate's control store, ``cycles_<mode>_nosss_64x64.npz``): the two
share every light path except none, so their difference is dermis's transport error alone, free of
the subsurface models' difference (Cycles' random walk vs dermis's skin profiles; region13's
section). Mean FLIP per scene/mode and region (validate's regions, supersampling, pixel filter and
FLIP), with the bounce light's orders at 1 (round 12's one bounce) and at
dermis.geometry.interreflection.BOUNCE_ORDERS (the series, bounce13), in one run.

    PYTHONPATH=src python benchmarks/transport_vs_control.py STORES [--json OUT]

STORES: a copy of benchmarks/cycles/stores (they must resume: nothing is rendered in Cycles). About
20 s per scene/mode and setting on llvmpipe.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from region_terms import SIZE, _render, _scene

SCENES = ("back-ears", "side", "front-key", "environment")


def score(stores: Path, name: str, mode: str, orders: int) -> dict:
    from dermis.blender.validate import CyclesAccumulation, _score, region_masks
    from dermis.errors import DermisError
    import dermis.geometry.interreflection as ir

    spec = mode == "spec"
    sc = _scene(name, spec)
    ctl = CyclesAccumulation(sc, SIZE, streams=1, sss=False, specular=spec, seed_base=1 << 20,
                             path=stores / name / f"cycles_{mode}_nosss_64x64.npz")
    if ctl.spp == 0:
        raise DermisError(f"{stores}: no Cycles control store for {name}/{mode} matches this tree")
    c = ctl.image(0)
    skin = c[..., 3] >= 0.999
    regions = region_masks(sc, SIZE, skin)
    kept = ir.BOUNCE_ORDERS
    ir.BOUNCE_ORDERS = orders  # read at each lighting change (dermis.gl.interreflection.BounceSeries)
    try:
        img = _render(_scene(name, spec), "lambert", None)
    finally:
        ir.BOUNCE_ORDERS = kept
    m, _ = _score(sc, c[..., :3], img, skin, regions)
    return {"ALL": m["flip"], **{r: d["flip"] for r, d in m["regions"].items()}}


def main(argv=None):
    import dermis.geometry.interreflection as ir

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stores", type=Path)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    out = {}
    for name in SCENES:
        for mode in ("spec", "nospec"):
            one, series = (score(args.stores, name, mode, n) for n in (1, ir.BOUNCE_ORDERS))
            out[f"{name}/{mode}"] = {"orders_1": one, f"orders_{ir.BOUNCE_ORDERS}": series}
            cells = "  ".join(f"{r} {one[r]:.4f}->{series[r]:.4f}" for r in one)
            print(f"{name}/{mode}: lambert vs Cycles no-SSS, 1 -> {ir.BOUNCE_ORDERS} orders: {cells}", flush=True)
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
