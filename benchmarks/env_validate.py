"""`dermis validate`'s numbers for one scene against a CACHED reference, so that real-time
changes (the environment's split sum) can be compared before and after without re-rendering the
offline reference each time.

    PYTHONPATH=src python benchmarks/env_validate.py CACHE_DIR [--scene examples/reference/environment.toml]
        [--size 256] [--spp 4] [--techniques tsd,ssss,preintegrated,lambert]

The reference (dermis.reference.render_reference, same arguments as `dermis validate`: pores off,
seed 0) is written once to CACHE_DIR/<scene>-<size>-<spp>spp.npz; the metrics are
dermis.reference.validate.metrics on the pixels the reference covers fully, as validate prints
them. Run with another tree's PYTHONPATH to score that tree against the same reference.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cache")
    ap.add_argument("--scene", default=str(REPO / "examples" / "reference" / "environment.toml"))
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--techniques", default="tsd,ssss,preintegrated,lambert")
    a = ap.parse_args(argv)
    import dermis
    from dermis.reference.validate import _render, metrics

    scene = dermis.load_scene(a.scene)
    scene.material.pore_strength = 0.0
    size = (a.size, a.size)
    cache = Path(a.cache)
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / f"{Path(a.scene).stem}-{a.size}-{a.spp}spp.npz"
    if not path.is_file():
        from dermis.reference.render import render_reference

        ref = render_reference(scene, size, spp=a.spp, seed=0, progress=False)
        np.savez_compressed(path, image=ref.image, coverage=ref.coverage)
    z = np.load(path)
    mask = z["coverage"] >= 1.0
    for t in a.techniques.split(","):
        img, _ = _render(scene, t, size)
        m, _ = metrics(scene, z["image"], img, mask)
        print(f"{t:14s} FLIP {m['flip']:.4f}  SSIM {m['ssim']:.4f}  relRMSE {m['rel_rmse']:.4f}")


if __name__ == "__main__":
    main()
