"""How far a change moved the image: this tree's renders against ``--before REV``'s, whole image
and the head's landmark crops (nose, eyes, lips, ears: benchmarks/crop_sheet.py's mesh landmarks,
the crop's mm square cut at full resolution, not resized), per scene and technique.

    PYTHONPATH=src python benchmarks/image_delta.py OUT_DIR --before REV [--size 768]
        [--techniques tsd lambert] [--scenes A.toml ...]

``--before double-sided``: this tree on a copy of each scene with [material] double_sided = true
(written beside the scene, removed after) against the scene as it is.

Prints a markdown table: max |display before - after| (the display image of the scene's exposure
and tone map, 0..1 per channel) and mean FLIP (flip-evaluator, LDR, as dermis validate) over the
rendered pixels. Renders are cached in OUT_DIR/renders as crop_sheet.py caches them.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import crop_sheet as cs  # noqa: E402


def delta(scene, a, b, box=None):
    import flip_evaluator as flip

    from dermis.reference.validate import display

    da = np.ascontiguousarray(display(scene, a)[..., :3], np.float32)
    db = np.ascontiguousarray(display(scene, b)[..., :3], np.float32)
    if box is not None:
        x0, y0, x1, y1 = box
        h, w = da.shape[:2]
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        da, db = da[y0:y1, x0:x1], db[y0:y1, x0:x1]
    fmap, _, _ = flip.evaluate(np.ascontiguousarray(da), np.ascontiguousarray(db), "LDR", applyMagma=False)
    return float(np.abs(da - db).max()), float(np.asarray(fmap).mean())


def main(argv=None):
    import dermis

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--before", required=True)
    ap.add_argument("--size", type=int, default=768)
    ap.add_argument("--techniques", nargs="+", default=["tsd", "lambert"])
    ap.add_argument("--scenes", nargs="+", default=[str(s) for s in cs.SCENES])
    ap.add_argument("--crop-mm", type=float, default=56.0)
    a = ap.parse_args(argv)
    out = Path(a.out)
    cache = out / "renders"
    cache.mkdir(parents=True, exist_ok=True)
    rows = ["| scene | technique | region | max abs | FLIP |", "|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        toggle = a.before == "double-sided"
        old_src = cs.REPO / "src" if toggle else cs.old_tree(a.before, Path(tmp))
        for scene_file in map(Path, a.scenes):
            if toggle:
                twin = scene_file.with_name(scene_file.stem + ".double-sided.toml")
                text = scene_file.read_text()
                assert "double_sided = false" in text, scene_file
                twin.write_text(text.replace("double_sided = false", "double_sided = true"))
                try:
                    before = cs.renders("double-sided", old_src, twin, a.techniques, a.size, cache)
                finally:
                    twin.unlink()
            else:
                before = cs.renders(a.before, old_src, scene_file, a.techniques, a.size, cache)
            after = cs.renders("work", cs.REPO / "src", scene_file, a.techniques, a.size, cache)
            sc = dermis.load_scene(scene_file)
            first = len(rows)
            mm = float(sc.mm_per_unit)
            lm = cs.landmarks(sc.mesh, mm)
            for t in a.techniques:
                img0, view, proj, eye = before[t]
                img1 = after[t][0]
                m, f = delta(sc, img0, img1)
                rows.append(f"| {scene_file.stem} | {t} | whole | {m:.4f} | {f:.5f} |")
                for name, (p, n) in lm.items():
                    if not cs.visible(sc.mesh, p, n, eye):
                        continue
                    box = cs.crop_box(p, proj @ view, view, proj, (img0.shape[1], img0.shape[0]),
                                      a.crop_mm * cs.CROP_SCALE[name], mm)
                    m, f = delta(sc, img0, img1, box)
                    rows.append(f"| {scene_file.stem} | {t} | {name} | {m:.4f} | {f:.5f} |")
            print("\n".join(rows[first:]), flush=True)
    text = "\n".join(rows)
    (out / "image_delta.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
