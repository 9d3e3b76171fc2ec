"""smooth_view's redistribution alone (round 22, branch denoise22): the shipped bake's cosine taps put through
bake.smooth_view as if they were a view term (G = 0, c = w / a0, so its cosine-view mean is w before the smoothing),
then the same lit sums as benchmarks/denoise_truth.py (the renderer's irradiance at the taps' uv) at the same points.
If this reproduces the view term's cosine mean (denoise_truth's (b)), the view grids' mean shift is smooth_view
moving each neighbour's own tap onto the point's nearest tap (often a far one), not the walks or the fit.

    PYTHONPATH=src python benchmarks/denoise_mechanism.py --irradiance DIR   (DIR from benchmarks/capture_irradiance.py)
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bake", default=str(Path.home() / ".cache/dermis/subsurface_transfer/e8f02f46042d7d6dc4570a4b.npz"))
    ap.add_argument("--irradiance", required=True)
    ap.add_argument("--points", type=int, default=20)
    ap.add_argument("--relative", action="store_true", help="a candidate fix (not the shipped code): each neighbour j's "
                    "taps matched to the point's by their offset from j (q - x_j + x_p), so own goes to own")
    a = ap.parse_args(argv)
    import dermis

    from denoise_truth import REGIONS, box_bake_points, uv_locate
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.gl.subsurface_transfer import transfer_numpy
    from dermis.subsurface_transfer import bake as B
    from dermis.subsurface_transfer import store

    bk = store.load(Path(a.bake))
    a0, a1 = B.view_mean_constants(1.4)
    sc = dermis.load_scene(str(REPO / "examples" / "reference" / "back-ears.toml"))
    mm = float(sc.mm_per_unit)
    pos = np.asarray(sc.mesh.positions, np.float64)
    idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
    uvs = np.asarray(texture_space_uvs(sc.mesh), np.float64)
    bp = B.bake_points(sc.mesh, mm)
    tp, _ = uv_locate(uvs[idx], pos[idx] * mm, bk.tap_uv.reshape(-1, 2).astype(np.float64))
    tp = tp.reshape(bk.tap_uv.shape[:2] + (3,))
    tp[:, 0] = bp.position
    tv = np.zeros(bk.tap_view.shape, np.float32)
    tv[..., 3] = bk.tap_weight / a0
    fake = dataclasses.replace(bk, tap_view=tv)
    sm = B.smooth_view(fake, bp, B.SMOOTH_VIEW_MM, tp, relative=a.relative).tap_view.astype(np.float64)
    mean = a0 * sm[..., 3]  # G = 0: the cosine-view mean is a0 c
    own_kept = mean[:, 0].sum() / bk.tap_weight[:, 0].astype(np.float64).sum()
    print(f"all {len(bp.position)} points: smooth_view keeps {own_kept:.3f} of the own taps' weight (sum, RGB pooled) on the own tap")
    for name, (sname, (x0, y0, x1, y1)) in REGIONS.items():
        s2 = dermis.load_scene(str(REPO / "examples" / "reference" / f"{sname}.toml"))
        j = box_bake_points(s2, pos, idx, mm, bp, (x0, y0, x1, y1), a.points)
        irr = np.load(Path(a.irradiance) / f"irr_{sname}.npy")
        g = lambda w: transfer_numpy(SimpleNamespace(tap_uv=bk.tap_uv[j], tap_weight=w.astype(np.float32)), irr)
        lit_a, lit_m = g(bk.tap_weight[j]), g(mean[j])
        V = transfer_numpy(SimpleNamespace(tap_uv=bk.tap_uv[j], tap_weight=bk.tap_weight[j], tap_view=bk.tap_view[j]), irr, view=True)
        lit_b = a0 * V[..., 3] + a1 * np.einsum("ncj,nj->nc", V[..., :3], bp.normal[j])
        print(f"{name:12s} {len(j)} pts, lit per point RGB: (a) cosine {lit_a.mean(0).round(4)}  cosine through smooth_view "
              f"{lit_m.mean(0).round(4)} ({(lit_m.sum(0) / lit_a.sum(0)).round(3)}x)  (b) view term {lit_b.mean(0).round(4)} "
              f"({(lit_b.sum(0) / lit_a.sum(0)).round(3)}x); own tap share: cosine {bk.tap_weight[j, 0, 0].sum() / bk.tap_weight[j, :, 0].sum():.2f}"
              f" smoothed {mean[j, 0, 0].sum() / mean[j, :, 0].sum():.2f} (red, uniform)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
