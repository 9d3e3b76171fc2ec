"""front-key's mouth line and lid crease, term by term, every technique, against Cycles at 768 px (issue 12, round 23,
mouth23; lobe22's ear_regions.py for the front-lit face).

    PYTHONPATH=src python benchmarks/mouth_terms.py render [--out /tmp/mouth_terms.npz] [--only VARIANT ...]
768 px, irradiance 1024^2, pore_strength 0 (as cycles_crops.py score): tsd whole, translucency=false (no far face,
no baked transfer), without the baked transfer's taps, without the skin-to-skin bounce (Scene.interreflection),
with rho_s 0 (specular off), without the environment (colour 0); ssss, preintegrated and lambert whole, without the
bounce and specular off. ~1-3 min a render on 2 shared cores.

    PYTHONPATH=src python benchmarks/mouth_terms.py table [--out ...] [--json J]
per box (box_red.py's: mouth line, lid crease): Cycles' stored crop (spec on; no 768 px no-SSS control is stored),
each render's mean linear red, its display red (dermis.reference.validate.display x 255) and the linear ratio to
Cycles; tsd's terms as differences of renders (far face = no transfer - no translucency; transfer = whole - no
transfer; bounce; specular; environment; rest = the near-face diffusion of the key light); and every technique with
Cycles' RANDOM_WALK head-on exit factor (green22: 0.914 / 0.827 / 0.808 of a Lambertian exit, R / G / B) applied to
its subsurface part (whole - specular), i.e. what the render would be if it left the skin as Cycles' walk does.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
from box_red import BOXES, cycles_frame  # noqa: E402

SIZE = 768
SCENE = "front-key"
EXIT = np.array([0.914, 0.827, 0.808])  # round 22 green22: Cycles' RANDOM_WALK exit / Lambertian exit, head-on


def _scene():
    import dermis

    sc = dermis.load_scene(REPO / "examples" / "reference" / f"{SCENE}.toml")
    sc.material.pore_strength = 0.0  # as cycles_crops.py score (the export has no pores)
    return sc


def _variants():
    def no_transfer(r):
        r.technique("tsd").transfer.add = lambda *a, **k: False  # the bake's taps not gathered

    def nospec(sc):
        sc.material.rho_s = 0.0

    def nobounce(sc):
        sc.interreflection = False

    def noenv(sc):
        sc.environment.color = (0.0, 0.0, 0.0)

    v = {  # name: (technique, renderer tweak, scene tweak)
        "tsd": ("tsd", None, None),
        "tsd_no_translucency": ("tsd", lambda r: r.technique("tsd", translucency=False), None),
        "tsd_no_transfer": ("tsd", no_transfer, None),
        "tsd_no_bounce": ("tsd", None, nobounce),
        "tsd_nospec": ("tsd", None, nospec),
        "tsd_no_env": ("tsd", None, noenv),
        "tsd_no_bounce_no_transfer": ("tsd", no_transfer, nobounce),  # beside the walks (no bounce in them)
    }
    for t in ("ssss", "preintegrated", "lambert"):
        v[t] = (t, None, None)
        v[f"{t}_no_bounce"] = (t, None, nobounce)
        v[f"{t}_nospec"] = (t, None, nospec)
    v["ssss_no_translucency"] = ("ssss", lambda r: r.technique("ssss", translucency=False), None)
    return v


def render(a) -> None:
    from dermis.renderer import Renderer

    out = dict(np.load(a.out)) if Path(a.out).exists() else {}
    for name, (t, tweak, stweak) in _variants().items():
        if (a.only and name not in a.only) or (not a.only and name in out):
            continue
        t0 = time.perf_counter()
        sc = _scene()
        if stweak:
            stweak(sc)
        with Renderer(sc, (SIZE, SIZE), irradiance_size=1024) as r:
            if tweak:
                tweak(r)
            out[name] = np.asarray(r.render(t))[..., :3].astype(np.float32)
        np.savez_compressed(a.out, **out)  # after each: a long batch on shared cores keeps what it made
        print(f"{name}: {time.perf_counter() - t0:.0f} s (load {os.getloadavg()[0]:.1f})", flush=True)


def table(a) -> dict:
    from dermis.reference.validate import display

    sc = _scene()
    img = dict(np.load(a.out))
    cyc = cycles_frame(SCENE)
    ok = np.isfinite(cyc[..., 0])
    cd = display(sc, np.nan_to_num(cyc))
    lev = lambda im, m: float(display(sc, im)[m, 0].mean() * 255)  # noqa: E731
    rep = {}
    for name, (x0, y0, x1, y1) in BOXES[SCENE].items():
        m = np.zeros(ok.shape, bool)
        m[y0:y1 + 1, x0:x1 + 1] = True
        m &= ok
        c = cyc[m].mean(0)
        e = {"box": [x0, y0, x1, y1], "px": int(m.sum()), "cycles": [float(x) for x in c],
             "cycles_level": float(cd[m, 0].mean() * 255)}
        print(f"{name} ({x0},{y0})-({x1},{y1}) {m.sum()} px: Cycles red {c[0]:.4f} ({e['cycles_level']:.1f})")
        for v, im in img.items():
            t = im[m].mean(0)
            row = {"red": float(t[0]), "level": lev(im, m), "ratio": float(t[0] / c[0])}
            tech = v.split("_")[0]
            if f"{tech}_nospec" in img:
                # Cycles' exit factor on the subsurface part only (the specular is a surface term: the whole
                # technique's, taken as the same in its variants; none in the _nospec ones)
                spec = 0.0 if v.endswith("_nospec") else img[tech] - img[f"{tech}_nospec"]
                ex = (im - spec) * (EXIT if tech != "lambert" else 1.0) + spec
                row.update(exit_red=float(ex[m, 0].mean()), exit_level=lev(ex, m), exit_ratio=float(ex[m, 0].mean() / c[0]))
            e[v] = row
            extra = (f"   with Cycles' exit {row['exit_red']:.4f} ({row['exit_level']:.1f}) {row['exit_ratio']:.3f}"
                     if "exit_red" in row else "")
            print(f"  {v:31s} {t[0]:.4f} ({row['level']:.1f}) / Cycles {row['ratio']:.3f}{extra}")
        for tech in ("tsd", "ssss", "preintegrated", "lambert"):
            if tech not in img:
                continue
            L = lambda k: lev(img[k], m) if k in img else float("nan")  # noqa: E731
            R = lambda k: float(img[k][m, 0].mean()) if k in img else float("nan")  # noqa: E731
            terms = {"specular": (R(tech) - R(f"{tech}_nospec"), L(tech) - L(f"{tech}_nospec")),
                     "bounce": (R(tech) - R(f"{tech}_no_bounce"), L(tech) - L(f"{tech}_no_bounce"))}
            if tech == "tsd":
                terms["transfer"] = (R("tsd") - R("tsd_no_transfer"), L("tsd") - L("tsd_no_transfer"))
                terms["far_face"] = (R("tsd_no_transfer") - R("tsd_no_translucency"),
                                     L("tsd_no_transfer") - L("tsd_no_translucency"))
                terms["environment"] = (R("tsd") - R("tsd_no_env"), L("tsd") - L("tsd_no_env"))
            if tech == "ssss":
                terms["translucency"] = (R("ssss") - R("ssss_no_translucency"), L("ssss") - L("ssss_no_translucency"))
            e[f"{tech}_terms"] = {k: {"red": v[0], "levels": v[1]} for k, v in terms.items()}
            print(f"  {tech} terms (linear red, display levels taken off by removing each): "
                  + ", ".join(f"{k} {v[0]:+.4f} ({v[1]:+.1f})" for k, v in terms.items()))
        rep[name] = e
    rep["control64"] = control64(img)
    if a.json:
        Path(a.json).write_text(json.dumps(rep, indent=1))
    return rep


CONTROL_BLOCKS = {"mouth line": (slice(53, 55), slice(30, 33)), "lid crease": (slice(30, 31), slice(36, 40))}
"""64 px pixels (rows, columns) that hold box_red.py's boxes (768 px = 12 x 64: the same framing)."""


def control64(img) -> dict:
    """Cycles' subsurface scattering against its own no-SSS control, where only the 64 px stores have the control
    (benchmarks/cycles/stores/front-key: cycles_spec_64x64 / cycles_spec_nosss_64x64, both spec on), beside each
    technique's render over lambert's, the 768 px renders averaged over the same 12 x 12 blocks; red."""
    def store(f):
        z = np.load(REPO / "benchmarks" / "cycles" / "stores" / SCENE / f"{f}_64x64.npz")
        return z["sums"].sum(0)[..., :3] / (z["sums"].shape[0] * int(z["spp"]))

    sss, nosss = store("cycles_spec"), store("cycles_spec_nosss")
    blk = lambda a: a.reshape(64, 12, 64, 12, -1).mean((1, 3))  # noqa: E731
    out = {}
    for name, s in CONTROL_BLOCKS.items():  # noqa: E741
        e = {"cycles_sss_over_nosss": [[round(float(x), 3) for x in r] for r in sss[s][..., 0] / nosss[s][..., 0]]}
        for t in ("tsd", "ssss", "preintegrated", "tsd_no_transfer", "tsd_no_bounce"):
            if t in img and "lambert" in img:
                ref = "lambert_no_bounce" if t.endswith("no_bounce") else "lambert"
                e[f"{t}_over_{ref}"] = [[round(float(x), 3) for x in r] for r in blk(img[t])[s][..., 0] / blk(img[ref])[s][..., 0]]
        print(f"{name} 64 px blocks {s}: " + "; ".join(f"{k} {v}" for k, v in e.items()))
        out[name] = e
    return out


def walks(a) -> dict:
    """Per box: ear_regions.walks (dermis's skin walk, index 1.4, and the Cycles-model walk, refracted and cosine
    entry; direct key light + the environment, no bounce) at the box's pixels in the head's geometry, against tsd
    without the bounce (the same light) and Cycles' crop."""
    import ear_regions

    sc = _scene()
    img = dict(np.load(a.out))
    cyc = cycles_frame(SCENE)
    rep = {}
    for name, (x0, y0, x1, y1) in BOXES[SCENE].items():
        box = (x0, y0, x1 + 1, y1 + 1)  # BOXES are inclusive, camera_hits' are not
        g = ear_regions.geometry(sc, box)
        m = g["tri"] >= 0
        w = ear_regions.walks(sc, g, m, a.walks, 0)
        t = {k: float(img[k][y0:y1 + 1, x0:x1 + 1, 0].reshape(-1)[m].mean()) for k in img}
        c = float(np.nanmean(cyc[y0:y1 + 1, x0:x1 + 1, 0].reshape(-1)[m]))
        w.update(tsd_no_bounce=t["tsd_no_bounce"], tsd_no_bounce_no_transfer=t["tsd_no_bounce_no_transfer"], lambert_no_bounce=t["lambert_no_bounce"], cycles_crop=c)
        print(f"{name}: {m.sum()} px, {a.walks} walks each, red: skin walk {w['skin'][0]:.4f} +- {w['skin'][1]:.4f} "
              f"(search-corrected {w['skin_exact']:.4f}), Cycles-model walk {w['cycles'][0]:.4f} +- {w['cycles'][1]:.4f} "
              f"(cosine entry {w['cycles_cosine'][0]:.4f}); tsd no bounce {t['tsd_no_bounce']:.4f} "
              f"(/ skin walk {t['tsd_no_bounce'] / w['skin_exact']:.3f}, / Cycles-model walk {t['tsd_no_bounce'] / w['cycles'][0]:.3f}),"
              f" tsd no bounce no transfer {t['tsd_no_bounce_no_transfer']:.4f} (/ skin walk "
              f"{t['tsd_no_bounce_no_transfer'] / w['skin_exact']:.3f}), "
              f"lambert no bounce {t['lambert_no_bounce']:.4f}; Cycles crop {c:.4f}", flush=True)
        rep[name] = w
    if a.json:
        Path(a.json).write_text(json.dumps(rep, indent=1))
    return rep


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("render", "table", "walks"))
    ap.add_argument("--walks", type=int, default=32)
    ap.add_argument("--out", default="/tmp/mouth_terms.npz")
    ap.add_argument("--only", nargs="+", default=None)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    {"render": render, "table": table, "walks": walks}[a.mode](a)


if __name__ == "__main__":
    main()
