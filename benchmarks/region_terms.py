"""Which of tsd's terms makes a region's difference to Cycles (issue 12, round 13 region13).

Per scene/mode and region of ``dermis validate --against cycles`` (its regions, its supersampled and
Cycles-filtered technique renders, its FLIP): the mean FLIP and the per-channel mean ratio to Cycles of
every technique, of tsd with one term switched off (the far-face translucency and the baked subsurface
transfer together, the transfer alone, the one-bounce interreflection), of lambert and ssss without the
bounce, and of Cycles without subsurface scattering (the control). Reads the converged stores (they must
resume: nothing is rendered in Cycles) and writes nothing but the printout (and, with --save DIR, the
64 x 64 arrays per scene/mode as .npz for per-pixel study).

    PYTHONPATH=src python benchmarks/region_terms.py STORES side/nospec front-key/spec ... [--save DIR]

STORES: a copy of benchmarks/cycles/stores (the Cycles accumulations, as validate's --images folder).
About 25 s a scene/mode on llvmpipe (load ~1).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

SUPERSAMPLE = 4
SIZE = (64, 64)
REGIONS = ("ALL", "eyelids", "nose_shadow_penumbra", "shadow_edge", "backlit_thin", "lips", "back_lit_ear")


def _scene(name, spec):
    import dermis

    sc = dermis.load_scene(f"examples/reference/{name}.toml")
    sc.material.pore_strength = 0.0  # as validate
    if not spec:
        sc.material.rho_s = 0.0
    return sc


def _no_transfer(r):
    r.technique("tsd").transfer.add = lambda *a, **k: False  # the bake's taps not gathered: T = far face only


def _no_bounce(sc):
    sc.interreflection = False


VARIANTS = {  # name: (technique, renderer tweak, scene edit)
    "tsd": ("tsd", None, None),
    "tsd-no-translucency": ("tsd", lambda r: r.technique("tsd", translucency=False), None),
    "tsd-no-transfer": ("tsd", _no_transfer, None),
    "tsd-no-bounce": ("tsd", None, _no_bounce),
    "ssss": ("ssss", None, None),
    "ssss-no-bounce": ("ssss", None, _no_bounce),
    "preintegrated": ("preintegrated", None, None),
    "lambert": ("lambert", None, None),
    "lambert-no-bounce": ("lambert", None, _no_bounce),
}


def _render(sc, technique, tweak):
    from dermis.blender.pixel_filter import reconstruct
    from dermis.renderer import Renderer

    with Renderer(sc, (SIZE[0] * SUPERSAMPLE, SIZE[1] * SUPERSAMPLE)) as r:
        if tweak:
            tweak(r)
        img = r.render(technique)
    return reconstruct(img[..., :3], SUPERSAMPLE)


def study(stores: Path, key: str, save: Path | None = None) -> dict:
    from dermis.blender.validate import CyclesAccumulation, _score, region_masks
    from dermis.errors import DermisError

    name, mode = key.split("/")
    spec = mode == "spec"
    sc = _scene(name, spec)
    acc = CyclesAccumulation(sc, SIZE, sss=True, specular=spec, path=stores / name / f"cycles_{mode}_64x64.npz")
    if acc.spp == 0:
        raise DermisError(f"{stores}: no Cycles store for {key} matches this tree (validate would render)")
    a, b = acc.image(0), acc.image(1)
    skin = (a[..., 3] >= 0.999) & (b[..., 3] >= 0.999)
    ref = 0.5 * (a[..., :3] + b[..., :3])
    regions = region_masks(sc, SIZE, skin)
    ctl = CyclesAccumulation(sc, SIZE, streams=1, sss=False, specular=spec, seed_base=1 << 20,
                             path=stores / name / f"cycles_{mode}_nosss_64x64.npz")
    imgs = {"control": ctl.image(0)[..., :3]}
    for v, (t, tweak, edit) in VARIANTS.items():
        s = _scene(name, spec)
        if edit:
            edit(s)
        imgs[v] = _render(s, t, tweak)
    if save:
        save.mkdir(parents=True, exist_ok=True)
        np.savez(save / f"{name}_{mode}.npz", ref=ref, skin=skin, **{f"region_{k}": m for k, m in regions.items()},
                 **{f"img_{k}": v for k, v in imgs.items()})
    out = {}
    for v, img in imgs.items():
        m, _ = _score(sc, ref, img, skin, regions)
        out[v] = {"ALL": (m["flip"], m["mean_ratio"]),
                  **{r: (d["flip"], d["mean_ratio"]) for r, d in m["regions"].items()}}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("stores", type=Path)
    ap.add_argument("keys", nargs="+", help="scene/mode, e.g. side/nospec")
    ap.add_argument("--save", type=Path)
    args = ap.parse_args(argv)
    for key in args.keys:
        res = study(args.stores, key, args.save)
        print(f"===== {key}")
        for r in REGIONS:
            if r not in res["tsd"]:
                continue
            print(f"  -- {r}")
            for v, d in res.items():
                f, mr = d[r]
                print(f"    {v:22s} FLIP {f:.4f}  mean ratio {mr[0]:.3f} {mr[1]:.3f} {mr[2]:.3f}")


if __name__ == "__main__":
    main()
