"""tsd at 768 px (irradiance 1024) with the shipped bake's re-walked points patched in (round 23, branch relview23).

    PYTHONPATH=src python benchmarks/relview_render.py TAPS.npz [own]

TAPS.npz: benchmarks/relview.py --save-taps (every bake point within 3.5 mm of what the boxes' pixels reach, per seed:
its uv, cosine weights and view taps). Per seed, the shipped bake (e8f02f) with those points replaced, their view term
smoothed by absolute matching (the shipped smooth_view), relative matching, not smoothed ("own": only smooth_own_taps'
1 mm; with the argument ``own``), or 0 ("x0": the cosine mean alone). Per box (box_red.py's and the nostril rim):
mean red, linear and display levels, beside the stored Cycles crops; the rendered view deviation (each - x0), its
mean and standard error over the seeds. Renders written beside TAPS.npz as *_renders.npz."""
import dataclasses, sys
from pathlib import Path
import numpy as np
REPO = Path(__file__).resolve().parent.parent
taps = np.load(sys.argv[1])
sys.path.insert(0, str(REPO / "benchmarks"))
import dermis
import dermis.subsurface_transfer.store as S
from dermis.renderer import Renderer
from dermis.reference.validate import display
from box_red import cycles_frame
bk = S.load(Path.home() / ".cache/dermis/subsurface_transfer/e8f02f46042d7d6dc4570a4b.npz")
near = taps["near"]
seeds = sorted({int(k.split("|")[0]) for k in taps.files if "|" in k})
boxes = {"front-key": {"mouth line": (370, 647, 390, 652), "lid crease": (440, 362, 470, 372), "nostril rim": (370, 495, 398, 548)},
         "back-ears": {"scapha": (340, 292, 362, 310), "helix rim": (384, 388, 404, 428), "lobe": (290, 520, 330, 565)}}
orig = S.find
MATCHES = ("absolute", "relative", "own", "x0") if sys.argv[2:] == ["own"] else ("absolute", "relative", "x0")


def variant(sd, match):
    uv, w, tv = bk.tap_uv.copy(), bk.tap_weight.copy(), bk.tap_view.copy()
    uv[near], w[near] = taps[f"{sd}|uv"], taps[f"{sd}|weight"]
    tv[near] = 0.0 if match == "x0" else taps[f"{sd}|{match}"]
    return dataclasses.replace(bk, tap_uv=uv, tap_weight=w, tap_view=tv)


out = {}
for scene, bx in boxes.items():
    sc = dermis.load_scene(str(REPO / "examples/reference" / f"{scene}.toml"))
    cyc = cycles_frame(scene); cd = display(sc, np.nan_to_num(cyc)); ok = np.isfinite(cyc[..., 0])
    res = {}
    for sd in seeds:
        for match in MATCHES:
            b = variant(sd, match)
            S.find = lambda scene, folder=None, b=b: b if orig(scene, folder) is not None else None
            with Renderer(sc, (768, 768), irradiance_size=1024) as r:
                im = np.asarray(r.render("tsd"))[..., :3].astype(np.float32)
            res[(sd, match)] = (im, display(sc, im))
            out[f"{scene}|{sd}|{match}"] = im
    S.find = orig
    for name, (x0, y0, x1, y1) in bx.items():
        m = np.zeros(ok.shape, bool); m[y0:y1 + 1, x0:x1 + 1] = True
        m &= ok
        print(f"{scene} {name}: Cycles {cyc[m, 0].mean():.4f} ({cd[m, 0].mean() * 255:.1f})", flush=True)
        for match in MATCHES:
            lin = np.array([res[(sd, match)][0][m, 0].mean() for sd in seeds])
            lev = np.array([res[(sd, match)][1][m, 0].mean() * 255 for sd in seeds])
            print(f"   {match:9s} per seed linear {lin.round(4)} display {lev.round(1)}", flush=True)
        for match in MATCHES[:-1]:
            dl = np.array([res[(sd, match)][0][m, 0].mean() - res[(sd, "x0")][0][m, 0].mean() for sd in seeds])
            dd = np.array([(res[(sd, match)][1][m, 0].mean() - res[(sd, "x0")][1][m, 0].mean()) * 255 for sd in seeds])
            se = (lambda x: x.std(ddof=1) / np.sqrt(len(x))) if len(seeds) > 1 else (lambda x: float("nan"))
            print(f"   {match:9s} - x0: linear {dl.mean():+.4f} +- {se(dl):.4f}, display {dd.mean():+.2f} +- {se(dd):.2f} levels", flush=True)
        dr = np.array([(res[(sd, 'relative')][1][m, 0].mean() - res[(sd, 'absolute')][1][m, 0].mean()) * 255 for sd in seeds])
        print(f"   relative - absolute: display {dr.round(2)} levels", flush=True)
np.savez_compressed(sys.argv[1].replace(".npz", "_renders.npz"), **out)
