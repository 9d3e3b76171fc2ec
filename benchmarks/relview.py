"""The view term's deviation at the camera's own view, shipped (smooth_view by absolute tap position) vs
relative matching (smooth_view(relative=True)), against fresh walks started along that view (round 23, branch
relview23; issue 12).

    PYTHONPATH=src python benchmarks/relview.py --irradiance DIR [--points 20] [--walks 4096] [--raw-seeds 0,1,2,3]
        [--raw-walks 192] [--truth EARLIER.npz] [--save-taps TAPS.npz] [--dump OUT.npz]

DIR: benchmarks/capture_irradiance.py's irr_<scene>.npy (tsd's gathered irradiance, the renderer's own light).
At ``--points`` bake points per region (denoise_truth.py's boxes and ray cast, the points whose facet faces the
camera by N.V > --min-cos; each point's view: from the scene's framed camera eye to the point, the camera's actual
view), per channel, summed over the taps under that irradiance at the taps' uv (gl.subsurface_transfer.transfer_numpy,
the gather's numpy twin):
  walks:    fresh walks along the view less fresh cosine-view walks (bake_transfer(views=) and bake_transfer at
            the same points, ``--walks`` each, independent seeds): T(v) - its cosine mean, the truth;
  shipped file: bake.view_deviation of the shipped bake's tap_view (e8f02f; what the shader adds);
  seed S absolute / relative / own tap 1 mm only: the shipped recipe's raw walks re-made (``--raw-walks``, default
            the bake's 192; seed S) at every bake point within 3.5 mm of the region's points (their smoothing
            neighbourhoods: 2.5 + 1 mm), smooth_own_taps, then smooth_view with absolute matching (the shipped
            recipe), relative=True, or no smooth_view; the deviation at the region's points. The shipped file's raw
            view taps are not recoverable: smooth_view sums every neighbour's taps into each of the point's taps.
            Another point set draws other walks, so each re-walk is an independent replicate of the shipped bake.
Standard errors over the region's points (paired differences against the walks beside; the 2.5 mm smoothing
correlates neighbouring points, so for the smoothed rows the spread over seeds is the honest error: printed per region).
``--save-taps``: the re-walked points' smoothed taps for benchmarks/relview_render.py.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--irradiance", required=True)
    ap.add_argument("--points", type=int, default=20)
    ap.add_argument("--walks", type=int, default=4096)
    ap.add_argument("--bake", default=str(Path.home() / ".cache/dermis/subsurface_transfer/e8f02f46042d7d6dc4570a4b.npz"))
    ap.add_argument("--regions", default="helix rim,scapha,lobe,lid crease,mouth line,nostril rim")
    ap.add_argument("--seed", type=int, default=101)
    ap.add_argument("--raw-seeds", default="0", help="the re-walked bakes' seeds (0: the shipped bake's)")
    ap.add_argument("--raw-walks", type=int, default=None, help="the re-walked bakes' walks (default: the shipped bake's)")
    ap.add_argument("--truth", help="an earlier --dump at the same points: its walks instead of new ones")
    ap.add_argument("--min-cos", type=float, default=0.15, help="only bake points whose facet faces the camera by more")
    ap.add_argument("--save-taps", help="write the re-walked bakes' smoothed view taps (absolute, relative; per seed) at "
                    "the re-walked bake points to this .npz (for a render with them patched into the shipped bake)")
    ap.add_argument("--dump")
    a = ap.parse_args(argv)
    import dermis
    from scipy.spatial import cKDTree

    from denoise_truth import REGIONS, box_bake_points, finish
    from dermis.framing import framed_camera
    from dermis.gl.subsurface_transfer import transfer_numpy
    from dermis.reference.render import camera_rays
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B
    from dermis.subsurface_transfer import store

    t0 = time.time()
    bk = store.load(Path(a.bake))
    eta = float(bk.meta["index"])
    scenes = {}
    sel, view, reg, reached = [], [], [], []
    names = a.regions.split(",")
    for name in names:
        sname, box = REGIONS[name]
        if sname not in scenes:
            scenes[sname] = dermis.load_scene(str(REPO / "examples" / "reference" / f"{sname}.toml"))
        sc = scenes[sname]
        mm = float(sc.mm_per_unit)
        pos = np.asarray(sc.mesh.positions, np.float64)
        idx = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)
        if "bp" not in scenes:
            scenes["bp"] = B.bake_points(sc.mesh, mm)
            assert np.allclose(scenes["bp"].uv, bk.point_uv, atol=1e-6), "bake points differ from the shipped bake's"
        bp = scenes["bp"]
        j = box_bake_points(sc, pos, idx, mm, bp, box, 10 ** 6)  # every bake point the box's pixels reach
        reached.append(j)
        eye = np.asarray(camera_rays(sc, (8, 8), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))[3], np.float64)
        v = bp.position[j] / mm - eye
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        seen = -(v * bp.normal[j]).sum(1) > a.min_cos  # facing the camera (a point behind a rim is not seen)
        j, v = j[seen], v[seen]
        pick = np.linspace(0, len(j) - 1, min(a.points, len(j))).astype(int)
        j, v = j[pick], v[pick]
        sel.append(j)
        view.append(v)  # towards the surface
        reg += [name] * len(j)
    bp = scenes["bp"]
    sc = next(s for k, s in scenes.items() if k != "bp")
    mm = float(sc.mm_per_unit)
    j = np.concatenate(sel)
    view = np.concatenate(view)
    reg = np.array(reg)
    fn = bp.normal[j]
    cosv = -(view * fn).sum(1)
    print(f"{len(j)} region points; N.V (facet) per region: " + ", ".join(
        f"{r} {np.median(cosv[reg == r]):.2f} [{cosv[reg == r].min():.2f}]" for r in names) + f"; {time.time() - t0:.0f} s", flush=True)
    albedo = np.asarray(mean_skin_albedo(sc.material), np.float64)
    media = B.skin_media(sc.profile, albedo)
    kernels = [B.flat_kernel(m) for m in media]

    def sub(ix):
        return B.BakePoints(bp.uv[ix], bp.position[ix], bp.triangle[ix], bp.normal[ix],
                            None if bp.thin is None else bp.thin[ix])

    irrs = {s: np.load(Path(a.irradiance) / f"irr_{s}.npy") for s in scenes if s != "bp"}

    def lit(uv, w):  # sum_k w_k I(uv_k) under each region's scene's irradiance, (n, 3)
        out = np.zeros((len(reg), 3))
        for r in names:
            m = reg == r
            out[m] = transfer_numpy(SimpleNamespace(tap_uv=uv[m], tap_weight=np.asarray(w[m], np.float32)), irrs[REGIONS[r][0]])
        return out

    dev = lambda tv: B.view_deviation(tv, view, fn, eta)
    rows, dump = {}, {"reg": reg, "cosv": cosv, "j": j}
    if a.truth:  # the walks of an earlier run at the same points
        z = np.load(a.truth)
        assert np.array_equal(z["j"], j), "the truth's points differ"
        rows["walks (view - cosine)"], rows["fresh cosine walks"] = z["walks"], z["fresh_cosine"]
    else:  # the truth: fresh walks along the view, and along cosine views, at the region's points
        fv = B.bake_transfer(sc.mesh, mm, sc.profile, albedo, walks=a.walks, points=sub(j), media=media, kernels=kernels,
                             seed=a.seed, views=view)
        print(f"fresh view walks {time.time() - t0:.0f} s", flush=True)
        fc = B.bake_transfer(sc.mesh, mm, sc.profile, albedo, walks=a.walks, points=sub(j), media=media, kernels=kernels,
                             seed=a.seed + 1)
        print(f"fresh cosine walks {time.time() - t0:.0f} s", flush=True)
        rows["fresh cosine walks"] = lit(fc.tap_uv, fc.tap_weight)
        rows["walks (view - cosine)"] = lit(fv.tap_uv, fv.tap_weight) - rows["fresh cosine walks"]
    dump["walks"], dump["fresh_cosine"] = rows["walks (view - cosine)"], rows["fresh cosine walks"]
    rows["shipped cosine mean (tap_weight)"] = lit(bk.tap_uv[j], bk.tap_weight[j])
    rows["shipped file"] = lit(bk.tap_uv[j], dev(bk.tap_view[j]))
    # the shipped recipe's raw walks re-made over the region's points' 3.5 mm neighbourhoods, per seed
    around = np.unique(np.concatenate(reached)) if a.save_taps else j  # for a render: every point the boxes reach
    near = np.unique(np.concatenate(cKDTree(bp.position).query_ball_point(bp.position[around], B.SMOOTH_VIEW_MM + B.SMOOTH_OWN_MM + 0.01)))
    at = np.searchsorted(near, j)
    seeds = [int(x) for x in a.raw_seeds.split(",")]
    raw_walks = int(bk.meta["walks"]) if a.raw_walks is None else a.raw_walks
    saved = {"near": near}
    for sd in seeds:
        raw = B.bake_transfer(sc.mesh, mm, sc.profile, albedo, walks=raw_walks, points=sub(near), media=media,
                              kernels=kernels, seed=sd)
        print(f"re-walked {len(near)} bake points at {raw_walks} walks, seed {sd}, {time.time() - t0:.0f} s", flush=True)
        own = B.smooth_own_taps(raw, sub(near))
        tp = own.tap_position.astype(np.float64).copy()
        tp[:, 0] = bp.position[near]
        saved[f"{sd}|uv"], saved[f"{sd}|weight"], saved[f"{sd}|own"] = own.tap_uv, own.tap_weight, own.tap_view
        for match in ("absolute", "relative"):
            sm = B.smooth_view(own, sub(near), B.SMOOTH_VIEW_MM, tp, relative=match == "relative")
            rows[f"seed {sd} {match}"] = lit(sm.tap_uv[at], dev(sm.tap_view[at]))
            saved[f"{sd}|{match}"] = sm.tap_view
            print(f"  seed {sd} {match}: own tap's share of |deviation| (red, uniform light) "
                  f"{np.abs(dev(sm.tap_view[at])[:, 0, 0]).sum() / np.abs(dev(sm.tap_view[at])[..., 0]).sum():.2f}", flush=True)
        rows[f"seed {sd} own tap 1 mm only"] = lit(own.tap_uv[at], dev(own.tap_view[at]))
        rows[f"seed {sd} cosine mean"] = lit(own.tap_uv[at], own.tap_weight[at])
    if a.save_taps:
        np.savez(a.save_taps, **saved)
    ref = rows["walks (view - cosine)"]
    for r in names:
        m = reg == r
        n = int(m.sum())
        print(f"== {r} ({REGIONS[r][0]}), {n} bake points, N.V median {np.median(cosv[m]):.2f}; per point mean RGB +- s.e. "
              f"(over the points) | less the walks, paired", flush=True)
        for k, v in rows.items():
            x = v[m]
            line = f"  {k:36s} {x.mean(0).round(4)} +- {(x.std(0) / np.sqrt(n)).round(4)}"
            if "cosine" not in k and k != "walks (view - cosine)":
                d = x - ref[m]
                line += f" | {d.mean(0).round(4)} +- {(d.std(0) / np.sqrt(n)).round(4)}, rms per point {np.sqrt((d ** 2).mean(0)).round(4)}"
            print(line, flush=True)
            dump[f"{r}|{k}"] = x
        wse = ref[m].std(0) / np.sqrt(n)
        for match in ("absolute", "relative", "own tap 1 mm only"):
            e = np.array([(rows[f"seed {sd} {match}"][m] - ref[m]).mean(0) for sd in seeds])  # (seeds, 3)
            se = np.sqrt(e.var(0, ddof=1) / len(seeds) + wse ** 2) if len(seeds) > 1 else wse
            print(f"  {match:18s} over {len(seeds)} seeds: region mean less the walks {e.mean(0).round(4)} +- {se.round(4)}; "
                  f"seed-to-seed s.d. {e.std(0, ddof=1).round(4) if len(seeds) > 1 else '-'}; rms over seeds {np.sqrt((e ** 2).mean(0)).round(4)}", flush=True)
    return finish(a.dump, dump, t0)


if __name__ == "__main__":
    sys.exit(main())
