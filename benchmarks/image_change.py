"""How far one tree's renders are from another's: FLIP (the validation's metric, LDR, on the
scene's display transform) between the "main" and "work" renders that benchmarks/crop_sheet.py
caches (OUT_DIR/renders/<tree>-<scene>-<size>-<hash>.npz), over the pixels either lit.

    PYTHONPATH=src python benchmarks/image_change.py OUT_DIR/renders [TECHNIQUE]

Prints per scene: mean FLIP, its 99.9th percentile and maximum, and the largest relative change
of the linear image (over pixels above 1e-3 of the 99th percentile).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    folder, technique = Path(argv[0]), (argv[1] if len(argv) > 1 else "ssss")
    import flip_evaluator as flip

    from dermis.api import load_scene
    from dermis.reference.validate import display

    for before in sorted(folder.glob("main-*.npz")):
        scene_name = before.name.split("-", 1)[1].rsplit("-", 2)[0]
        after = next(folder.glob(f"work-{scene_name}-*.npz"), None)
        if after is None:
            continue
        a, b = np.load(after)[f"img_{technique}"], np.load(before)[f"img_{technique}"]
        path = REPO / "examples" / f"{scene_name}.toml"
        path = path if path.exists() else REPO / "examples" / "reference" / f"{scene_name}.toml"
        scene = load_scene(path)
        fmap, _, _ = flip.evaluate(np.ascontiguousarray(display(scene, b), np.float32),
                                   np.ascontiguousarray(display(scene, a), np.float32), "LDR", applyMagma=False)
        fmap = np.asarray(fmap, np.float32).reshape(a.shape[:2])
        lit = (a.max(axis=2) > 0) | (b.max(axis=2) > 0)
        floor = 1e-3 * float(np.percentile(np.abs(b[lit]), 99))
        rel = np.abs(a - b)[lit] / np.maximum(np.abs(b[lit]), floor)
        f = fmap[lit]
        print(f"{scene_name:18s} {technique}: FLIP mean {f.mean():.4f}, p99.9 {np.percentile(f, 99.9):.4f}, "
              f"max {f.max():.4f}; relative change p99 {np.percentile(rel, 99):.4f}, max {rel.max():.3f} ({lit.sum()} px)")


if __name__ == "__main__":
    main()
