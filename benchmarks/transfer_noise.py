"""The baked subsurface transfer's Monte Carlo noise (issue 12, round 11: the mottle beside thin parts).

    PYTHONPATH=src nice -n 10 python benchmarks/transfer_noise.py bake SCENE.toml OUT_DIR
        the head's bake as `python -m dermis.subsurface_transfer` makes it (--seed, default 0 here), written twice: OUT_DIR/raw.npz
        (before the significance shrinkage: round 10's taps) and OUT_DIR/cache/subsurface_transfer/<key>.npz
        (the shipped bake; DERMIS_CACHE_DIR=OUT_DIR/cache renders with it), with the points (points.npz)
    PYTHONPATH=src nice -n 10 python benchmarks/transfer_noise.py reference SCENE.toml OUT_DIR [--walks 1536]
        a bake of two patches (the cheek under the +x eye, the +x ear's helix) with many more walks:
        OUT_DIR/reference.npz, the independent reference of the per-point net transfer
    PYTHONPATH=src python benchmarks/transfer_noise.py compare SCENE.toml OUT_DIR
        the RMS difference of the per-point net (the taps' sum, per channel) against the reference,
        round 10's taps and the shrunk ones, per patch
    PYTHONPATH=src python benchmarks/transfer_noise.py ratio SCENE.toml OUT_DIR [--size 768]
        tsd rendered without a bake, with raw.npz (round 10's taps) and with the shipped bake: the
        luminance ratio (with / without) and its high-pass (less its 6 x 6 px box mean) std over the lit
        skin the round-10 bake changes (OUT_DIR/ratio-<scene>-<size>.npz and a line of JSON)
    PYTHONPATH=src python benchmarks/transfer_noise.py ear examples/reference/back-ears.toml OUT_DIR [--size 384]
        tsd's mean red over validate's back_lit_ear region, the three bakes as `ratio`
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "src"))

# the patches (mm about the nose tip, as benchmarks/crop_sheet.py's landmarks): centre, radius
PATCHES = {"cheek": ((28.0, 12.0), 6.0), "helix": (None, 7.0)}  # cheek: under the +x eye


def _points(scene):
    from dermis.subsurface_transfer.bake import bake_points

    return bake_points(scene.mesh, scene.mm_per_unit)


def _save_points(path, pts):
    np.savez(path, uv=pts.uv, position=pts.position, triangle=pts.triangle, normal=pts.normal)


def _load_points(path):
    from dermis.subsurface_transfer.bake import BakePoints

    with np.load(path) as z:
        return BakePoints(z["uv"], z["position"], z["triangle"], z["normal"])


def cmd_bake(a):
    import dermis
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import store
    from dermis.subsurface_transfer.bake import bake_transfer, denoise, recipe_key, smooth_own_taps

    sc = dermis.load_scene(a.scene)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    pts = _points(sc)
    _save_points(out / "points.npz", pts)
    bake = bake_transfer(sc.mesh, sc.mm_per_unit, sc.profile, mean_skin_albedo(sc.material), points=pts, seed=a.seed,
                         progress=lambda s: print(f"{time.perf_counter() - t0:7.1f} s {s}", flush=True))
    raw = smooth_own_taps(bake, pts)  # round 10's bake
    store.save(raw, out / "raw.npz", store.mesh_key(sc.mesh), sc.mm_per_unit)
    final = denoise(bake, pts)  # as store.bake_scene
    final.meta["recipe"] = recipe_key()  # what store.find checks
    p = store.path_for(sc.mesh, out / "cache" / store.CACHE_SUBFOLDER)
    store.save(final, p, store.mesh_key(sc.mesh), sc.mm_per_unit)
    print(f"{time.perf_counter() - t0:.1f} s; {p} {p.stat().st_size / 1e6:.2f} MB; {json.dumps(final.meta)}")


def patch_mask(scene, pts):
    """{patch: bool mask over the bake points}: the cheek disc (3-D distance to the landmark) and the
    +x ear's helix (the ear's outermost points: crop_sheet's ear landmark)."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    from crop_sheet import landmarks

    mm = float(scene.mm_per_unit)
    pos = np.asarray(scene.mesh.positions, np.float64) * mm
    tip = pos[np.argmax(pos[:, 2])]
    out = {}
    (cx, cy), r = PATCHES["cheek"]
    sel = np.nonzero((np.abs(pos[:, 0] - tip[0] - cx) < 3) & (np.abs(pos[:, 1] - tip[1] - cy) < 3))[0]
    centre = pos[sel[np.argmax(pos[sel, 2])]]
    out["cheek"] = np.linalg.norm(pts.position - centre, axis=1) < r
    ear = np.asarray(landmarks(scene.mesh, mm)["ear +x"][0], np.float64) * mm
    out["helix"] = np.linalg.norm(pts.position - ear, axis=1) < PATCHES["helix"][1]
    return out


def cmd_reference(a):
    import dermis
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer.bake import BakePoints, bake_transfer, smooth_own_taps

    sc = dermis.load_scene(a.scene)
    out = Path(a.out)
    pts = _load_points(out / "points.npz") if (out / "points.npz").is_file() else _points(sc)
    masks = patch_mask(sc, pts)
    sel = np.nonzero(masks["cheek"] | masks["helix"])[0]
    sub = BakePoints(pts.uv[sel], pts.position[sel], pts.triangle[sel], pts.normal[sel])
    t0 = time.perf_counter()
    bake = bake_transfer(sc.mesh, sc.mm_per_unit, sc.profile, mean_skin_albedo(sc.material), points=sub, walks=a.walks,
                         seed=a.seed, progress=lambda s: print(f"{time.perf_counter() - t0:7.1f} s {s}", flush=True))
    bake = smooth_own_taps(bake, sub)
    np.savez(out / "reference.npz", index=sel, total=bake.total, excess=bake.excess, excess_cov=bake.excess_cov,
             walks=a.walks, seconds=time.perf_counter() - t0)
    print(f"{len(sel)} points x {a.walks} walks: {time.perf_counter() - t0:.1f} s")


def interior(pts, mask, margin_mm):
    """The points of ``mask`` at least ``margin_mm`` from any point outside it (their 1 mm own-tap
    smoothing saw the same neighbours in the patch's bake and in the full one)."""
    from scipy.spatial import cKDTree

    if mask.all():
        return mask
    d, _ = cKDTree(pts.position[~mask]).query(pts.position[mask])
    out = np.zeros_like(mask)
    out[np.nonzero(mask)[0][d >= margin_mm]] = True
    return out


def cmd_compare(a):
    """Per patch (interior points: 1.5 mm inside), the RMS over points of (bake's net - reference's
    net) per channel: the reference is the patch's bake with --walks (default 8x) and its own seed,
    unsmoothed (its per-point net: the within + beyond excess), whose own noise is printed beside
    (its standard errors' RMS). Bakes: round 10 (raw.npz), the shipped one, and any
    OUT_DIR/variants/<name>/*.npz."""
    import dermis
    from dermis.subsurface_transfer import store

    out = Path(a.out)
    sc = dermis.load_scene(a.scene)
    pts = _load_points(out / "points.npz")
    ref = np.load(out / "reference.npz")
    bakes = {"round 10": out / "raw.npz", "shipped": store.path_for(sc.mesh, out / "cache" / store.CACHE_SUBFOLDER)}
    for f in sorted((out / "variants").glob("*/*.npz")):
        bakes[f.parent.name] = f
    masks = patch_mask(sc, pts)
    n = len(pts.uv)
    ref_net = np.full((n, 3), np.nan)
    ref_net[ref["index"]] = ref["excess"].sum(2)
    cov = ref["excess_cov"]
    ref_se = np.full((n, 3), np.nan)
    ref_se[ref["index"]] = np.sqrt(np.maximum(cov[..., 0] + cov[..., 1] + 2.0 * cov[..., 2], 0.0))
    nets = {k: store.load(f).total.astype(np.float64) for k, f in bakes.items()}
    rows = []
    for name, m in masks.items():
        m = m & np.isfinite(ref_net[:, 0]) & interior(pts, m, 1.5)
        row = {"patch": name, "points": int(m.sum()), "reference walks": int(ref["walks"]),
               "reference mean net RGB": ref_net[m].mean(0).round(4).tolist(),
               "reference own noise (rms se) RGB": np.sqrt((ref_se[m] ** 2).mean(0)).round(4).tolist()}
        for k, net in nets.items():
            row[k] = {"rms diff RGB": np.sqrt(((net[m] - ref_net[m]) ** 2).mean(0)).round(4).tolist(),
                      "mean net RGB": net[m].mean(0).round(4).tolist()}
        rows.append(row)
    print(json.dumps(rows, indent=1))


def _cache_with(out: Path, name: str, bake_file: Path | None, scene) -> Path:
    """A cache folder whose subsurface_transfer/ holds only ``bake_file`` (under the mesh's name) and
    whose other caches are the user's (symlinks: the visibility and interreflection bakes are reused)."""
    import os

    from dermis.profiles.scene_skin import _cache_folder
    from dermis.subsurface_transfer import store

    home = _cache_folder()
    d = out / name
    d.mkdir(parents=True, exist_ok=True)
    if home is not None and home.is_dir():
        for sub in home.iterdir():
            if sub.name != store.CACHE_SUBFOLDER and not (d / sub.name).exists():
                os.symlink(sub, d / sub.name)
    st = d / store.CACHE_SUBFOLDER
    st.mkdir(exist_ok=True)
    target = store.path_for(scene.mesh, st)
    if target.exists() or target.is_symlink():
        target.unlink()
    if bake_file is not None:
        os.symlink(Path(bake_file).resolve(), target)
    return d


def pixel_parts(scene_file, size, band_mm: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """(ears, band): (size, size) bool masks of the pixels whose surface point lies more than
    EAR_LATERAL_MM to the side of the nose tip (dermis.blender.validate's ear test without its
    height/depth box: the whole ear), and of those farther than ``band_mm`` from every thin texel
    (dermis.subsurface_transfer.bake.thin_points: the thick skin of the bake's band, where the
    transfer's expectation is ~0)."""
    import dermis
    from dermis.blender.validate import EAR_LATERAL_MM
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays
    from dermis.subsurface_transfer.bake import thin_points
    from scipy.spatial import cKDTree

    sc = dermis.load_scene(scene_file)
    mm = float(sc.mm_per_unit)
    pos = np.asarray(sc.mesh.positions, np.float64)
    o, d, tmax, _ = camera_rays(sc, (size, size), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    t, tri, _ = RayCaster(pos, np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3)).closest_hit(o, d, 0.0, tmax)
    P = o + d * np.where(tri >= 0, t, 0)[:, None]
    tip = pos[np.argmax(pos[:, 2])]
    ears = (tri >= 0) & (np.abs(P[:, 0] - tip[0]) * mm > EAR_LATERAL_MM)
    dist, _ = cKDTree(thin_points(sc.mesh, mm).position).query(P * mm)
    band = (tri >= 0) & (dist > band_mm)
    return ears.reshape(size, size), band.reshape(size, size)


def luminance(img):
    return img[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def highpass_std(ratio, mask, box: int = 6):
    """std of ratio less its box x box mean, over the pixels of ``mask`` whose whole box lies in it."""
    from scipy.ndimage import binary_erosion, uniform_filter

    r = np.where(mask, ratio, 0.0)
    m = mask.astype(np.float64)
    inner = binary_erosion(mask, np.ones((box + 1, box + 1), bool))
    hp = r - uniform_filter(r, box) / np.maximum(uniform_filter(m, box), 1e-9)
    return float(hp[inner].std()), int(inner.sum()), hp


def render_three(a) -> dict:
    """tsd of ``a.scene`` at ``a.size``: {"none", "round10", "shipped"} -> linear image (no bake, round
    10's taps raw.npz, the shipped shrunk bake; each from a cache folder of its own)."""
    import os

    import dermis
    from dermis.renderer import Renderer
    from dermis.subsurface_transfer import store

    out = Path(a.out)
    sc = dermis.load_scene(a.scene)
    shipped = store.path_for(sc.mesh, out / "cache" / store.CACHE_SUBFOLDER)
    imgs = {}
    before = os.environ.get("DERMIS_CACHE_DIR")
    for name, f in (("none", None), ("round10", out / "raw.npz"), ("shipped", shipped)):
        os.environ["DERMIS_CACHE_DIR"] = str(_cache_with(out, f"cache-{name}", f, sc))
        sc = dermis.load_scene(a.scene)
        t0 = time.perf_counter()
        with Renderer(sc, (a.size, a.size), irradiance_size=1024) as r:
            imgs[name] = r.render("tsd").astype(np.float64)
            ran = "tsd_subsurface_transfer" in r.last_frame.passes_run
        assert ran == (f is not None), (name, ran)
        print(f"{name}: {time.perf_counter() - t0:.1f} s", flush=True)
    if before is None:
        os.environ.pop("DERMIS_CACHE_DIR")
    else:
        os.environ["DERMIS_CACHE_DIR"] = before
    return imgs


def cmd_ear(a):
    """Mean red over validate's back_lit_ear region (dermis.blender.validate.region_masks at the render's
    size, every pixel counted as skin: no Cycles store here) without a bake, with round 10's taps and
    with the shipped bake; the share of round 10's gain over no transfer that the shipped bake keeps."""
    import dermis
    from dermis.blender.validate import region_masks

    imgs = render_three(a)
    sc = dermis.load_scene(a.scene)
    ear = region_masks(sc, (a.size, a.size), np.ones((a.size, a.size), bool))["back_lit_ear"]
    red = {k: float(v[..., 0][ear].mean()) for k, v in imgs.items()}
    res = {"scene": Path(a.scene).stem, "size": a.size, "ear px": int(ear.sum()), "red": red,
           "gain kept": (red["shipped"] - red["none"]) / (red["round10"] - red["none"]),
           "green gain kept": float((imgs["shipped"][..., 1][ear].mean() - imgs["none"][..., 1][ear].mean())
                                    / (imgs["round10"][..., 1][ear].mean() - imgs["none"][..., 1][ear].mean()))}
    print(json.dumps(res))


def highpass_gauss_std(ratio, mask, sigma: float = 6.0) -> float:
    """std of ratio less its Gaussian (``sigma`` px) mean over ``mask``, over the pixels 2 sigma inside it."""
    from scipy.ndimage import binary_erosion, gaussian_filter

    r = np.where(mask, ratio, 0.0)
    lo = gaussian_filter(r, sigma) / np.maximum(gaussian_filter(mask.astype(np.float64), sigma), 1e-9)
    inner = binary_erosion(mask, iterations=int(2 * sigma))
    return float((r - lo)[inner].std())


def cmd_ratio(a):
    out = Path(a.out)
    imgs = render_three(a)
    L0 = luminance(imgs["none"])
    lit = L0 > 0.05 * np.percentile(L0[L0 > 0], 99)
    ratios = {k: luminance(imgs[k]) / np.maximum(L0, 1e-12) for k in ("round10", "shipped")}
    from scipy.ndimage import binary_closing

    # the lit skin round 10's bake changes (holes where its ratio happens to be ~1 closed)
    changed = lit & binary_closing(np.abs(ratios["round10"] - 1.0) > 1e-4, np.ones((5, 5), bool))
    ears, band = pixel_parts(a.scene, a.size)
    face = changed & ~ears
    band = face & band
    box = max(2, round(6 * a.size / 768))  # < 6 px at 768 px
    res = {"scene": Path(a.scene).stem, "size": a.size, "box px": box, "lit changed px": int(changed.sum()),
           "of which face": int(face.sum()), "of which band": int(band.sum())}
    for k, rt in ratios.items():
        res[k] = {}
        for where, m in (("all", changed), ("face (no ears)", face), ("band (thick skin beside)", band)):
            if m.sum() < 100:
                continue
            sd, npx, hp = highpass_std(rt, m, box)
            sg = highpass_gauss_std(rt, m, box)
            res[k][where] = {"highpass std (box)": round(sd, 5), "highpass std (gaussian)": round(sg, 5), "px": npx, "ratio mean": round(float(rt[m].mean()), 5),
                             "ratio p1-p99": np.percentile(rt[m], [1, 99]).round(4).tolist()}
    np.savez_compressed(out / f"ratio-{Path(a.scene).stem}-{a.size}.npz", **{k: v.astype(np.float32) for k, v in imgs.items()},
                        changed=changed)
    print(json.dumps(res))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cmd", choices=("bake", "reference", "compare", "ratio", "ear"))
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--walks", type=int, default=1536)
    ap.add_argument("--seed", type=int, default=None, help="bake: 0, reference: 101")
    ap.add_argument("--size", type=int, default=768)
    a = ap.parse_args(argv)
    if a.seed is None:
        a.seed = 101 if a.cmd == "reference" else 0
    {"bake": cmd_bake, "reference": cmd_reference, "compare": cmd_compare, "ratio": cmd_ratio, "ear": cmd_ear}[a.cmd](a)


if __name__ == "__main__":
    main()
