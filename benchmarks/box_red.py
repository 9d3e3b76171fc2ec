"""Mean red of pixel boxes in crop_sheet.py's cached 768 px renders (OUT_DIR/renders/*.npz) against the stored
Cycles crops (benchmarks/cycles/crops), linear and in display 8-bit levels (issue 12, round 22 view22: the
mouth line, the lid crease, the back-lit ear's scapha, helix and lobe; the boxes of rounds 21 ears21 / taps21).

    PYTHONPATH=src python benchmarks/box_red.py OUT_DIR/renders

Per box: Cycles' mean linear red and the mean of its display red (dermis.reference.validate.display, x 255);
per render file (tree) and technique the same and the linear ratio to Cycles. Cycles pixels with coverage < 1
(the crop's background) are left out of both.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
BOXES = {  # scene: {name: (x0, y0, x1, y1) inclusive}
    "front-key": {"mouth line": (370, 647, 390, 652), "lid crease": (440, 362, 470, 372)},
    "back-ears": {"scapha": (340, 292, 362, 310), "helix": (360, 330, 390, 420), "helix rim": (384, 388, 404, 428), "lobe": (290, 520, 330, 565)},
}


def cycles_frame(scene: str, size: int = 768):
    frame, cov = np.full((size, size, 3), np.nan, np.float32), np.zeros((size, size), np.float32)
    for f in sorted((REPO / "benchmarks" / "cycles" / "crops").glob(f"{scene}--*.npz")):
        z = np.load(f)
        meta = json.loads(str(z["meta"]))
        if meta["size"] != size:
            continue
        x0, y0, x1, y1 = meta["box"]
        frame[y0:y1, x0:x1] = z["rgb"].view(np.float16).astype(np.float32)  # as cycles_crops.load_crop
        cov[y0:y1, x0:x1] = z["coverage"].astype(np.float32) / 255.0
    frame[cov < 0.999] = np.nan
    return frame


def main(argv=None) -> int:
    import dermis
    from dermis.reference.validate import display

    folder = Path((argv or sys.argv[1:])[0])
    for scene, boxes in BOXES.items():
        sc = dermis.load_scene(REPO / "examples" / "reference" / f"{scene}.toml")
        cyc = cycles_frame(scene)
        cyc_d = display(sc, np.nan_to_num(cyc))
        ok = np.isfinite(cyc[..., 0])
        files = sorted(folder.glob(f"*-{scene}-768-*.npz"))
        for name, (x0, y0, x1, y1) in boxes.items():
            m = np.zeros(cyc.shape[:2], bool)
            m[y0:y1 + 1, x0:x1 + 1] = True
            m &= ok
            c_lin = float(cyc[m, 0].mean())
            print(f"{scene} {name} ({x0},{y0})-({x1},{y1}), {m.sum()} px: Cycles {c_lin:.4f} ({cyc_d[m, 0].mean() * 255:.0f})")
            for f in files:
                z = np.load(f)
                for k in z.files:
                    if k.startswith("img_"):
                        img = z[k][..., :3].astype(np.float64)
                        d = display(sc, img.astype(np.float32))
                        lin = float(img[m, 0].mean())
                        print(f"    {f.name.split('-')[0]:6s} {k[4:]:14s} {lin:.4f} ({d[m, 0].mean() * 255:.0f})  ratio {lin / c_lin:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
