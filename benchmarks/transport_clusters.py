"""Where lambert departs from Cycles' control, per pixel, and which of its terms makes each cluster (issue 12, round 16).

Reads the 64 px arrays ``benchmarks/region_terms.py STORES <scene>/nospec --save DIR`` writes (lambert and
Cycles' render without subsurface scattering, the control), marks the skin pixels whose lambert / control
ratio leaves [0.87, 1.15] in any channel, groups them into 8-connected clusters and ranks the clusters by
their share of FLIP(lambert, control) (validate's metrics). For the clusters of at least 4 pixels (and any
pixels given with --pixel y,x) it re-renders lambert without the environment, without the lights, without
shadows and without the bounce (region_terms' scene and renderer) and prints each as a fraction of the control.

    PYTHONPATH=src python benchmarks/transport_clusters.py DIR side back-ears ... [--pixel 62,21]

About 15 s a scene on llvmpipe (5 renders at 256 px, reduced to 64).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from region_terms import _no_bounce, _render, _scene

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
BAND = (0.87, 1.15)


def _no_env(sc):
    sc.environment.color = (0.0, 0.0, 0.0)
    sc.environment.image = None


def _no_lights(sc):
    sc.lights = []


def _no_shadows(sc):
    for light in sc.lights:
        light.cast_shadows = False


EDITS = {"no-environment": _no_env, "no-lights": _no_lights, "no-shadows": _no_shadows, "no-bounce": _no_bounce}


def clusters(control, lambert, skin, fmap):
    """[(share of the FLIP, mask, mean ratio per channel)] of the out-of-band clusters, largest share first."""
    from scipy import ndimage

    ratio = lambert / np.maximum(control, 1e-6)
    bad = skin & ((ratio < BAND[0]) | (ratio > BAND[1])).any(-1)
    lab, n = ndimage.label(bad, structure=np.ones((3, 3)))
    out = [(fmap[lab == i].sum() / fmap[skin].sum(), lab == i,
            lambert[lab == i].mean(0) / control[lab == i].mean(0)) for i in range(1, n + 1)]
    return sorted(out, key=lambda c: -c[0])


def study(saved: Path, name: str, pixels=()):
    from dermis.reference.validate import metrics

    d = np.load(saved / f"{name}_nospec.npz")
    control, lambert, skin = d["img_control"], d["img_lambert"], d["skin"]
    _, fmap = metrics(_scene(name, False), control, lambert, skin)
    lr = np.log(np.maximum(lambert @ LUMINANCE, 1e-6) / np.maximum(control @ LUMINANCE, 1e-6))[skin]
    found = clusters(control, lambert, skin, fmap)
    print(f"===== {name}/nospec: FLIP(lambert, control) {fmap[skin].mean():.4f}, rms log-lum ratio "
          f"{np.sqrt(np.mean(lr ** 2)):.4f}, {sum(int(m.sum()) for _, m, _ in found)} px out of band")
    masks = []
    for share, m, r in found:
        ys, xs = np.nonzero(m)
        print(f"  {int(m.sum()):3d} px y {ys.min()}-{ys.max()} x {xs.min()}-{xs.max()}: {100 * share:4.1f} % of the FLIP,"
              f" ratio {r[0]:.2f} {r[1]:.2f} {r[2]:.2f}")
        if m.sum() >= 4:
            masks.append((f"y {ys.min()}-{ys.max()} x {xs.min()}-{xs.max()}", m))
    for y, x in pixels:
        m = np.zeros_like(skin)
        m[y, x] = True
        masks.append((f"pixel ({y}, {x})", m))
    if not masks:
        return
    variants = {"lambert": lambert}
    for v, edit in EDITS.items():
        sc = _scene(name, False)
        edit(sc)
        variants[v] = _render(sc, "lambert", None)
    for label, m in masks:
        c = control[m].mean(0)
        print(f"  -- {label}, as fractions of the control")
        for v, img in variants.items():
            f = img[m].mean(0) / c
            print(f"    {v:16s} {f[0]:.3f} {f[1]:.3f} {f[2]:.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("saved", type=Path, help="region_terms.py's --save folder")
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--pixel", action="append", default=[], help="y,x at 64 px (repeatable)")
    args = ap.parse_args(argv)
    pixels = [tuple(int(v) for v in p.split(",")) for p in args.pixel]
    for name in args.scenes:
        study(args.saved, name, pixels if name == args.scenes[0] else ())


if __name__ == "__main__":
    main()
