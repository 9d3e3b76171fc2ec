"""The closed mouth's line against Cycles' stored 768 px lips crop, per pixel and per term (issue 12,
round 20, branch mouth20: tsd's crease lighter and thinner than the path tracer's).

    PYTHONPATH=src python benchmarks/mouth_line.py geometry SCENE.toml --columns 380,400 --rows 642,660
    PYTHONPATH=src python benchmarks/mouth_line.py render SCENE.toml OUT.npz [--irradiance-size N]
        [--shadow-size N] [--variants tsd,tsd_notrans,...]
    PYTHONPATH=src python benchmarks/mouth_line.py score SCENE.toml OUT.npz [...]
        [--columns 380,400 --rows 646,656]   (FLIP over the crop and the line windows; luminance columns)

``geometry``: the camera's ray through each pixel centre of the given columns (the frame the renderer
draws: dermis.framing.framed_camera), its triangle, interpolated N.L of the first light and N.V, whether
the shadow ray towards that light is blocked (Embree), its texture-space uv in texels of an irradiance
texture of --texels (1024) and the step to the pixel above in surface mm and in texels: where the two
lips meet, how far apart their sides lie in the layout.

``render``: the lips crop window of 768 px frames (pore_strength 0, as cycles_crops.py score) of tsd
with one term left out at a time (VARIANTS: the one bounce, the ambient, the translucency texture --
the far face and the baked transfer --, the pixel detail) and preintegrated / lambert.

``score``: per variant the crop's FLIP against the stored crop (benchmarks/cycles/crops, the same
metric as cycles_crops.py score), the mean FLIP in the line's windows (frame x 353-413, y 642-655:
where round 19 found tsd behind preintegrated; x 233-258, y 636-649) and the luminance down the columns.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
SIZE = 768
# the frame windows of the mouth line where tsd's FLIP exceeds preintegrated's (x0, y0, x1, y1)
WINDOWS = {"line+x": (353, 642, 413, 655), "line-x": (233, 636, 258, 649)}
# name: (technique, interreflection, ambient, technique options); None options: the defaults
VARIANTS = {
    "tsd": ("tsd", True, True, {}),
    "tsd_nobounce": ("tsd", False, True, {}),
    "tsd_noambient": ("tsd", True, False, {}),
    "tsd_notranslucency": ("tsd", True, True, {"translucency": False}),
    "tsd_nodetail": ("tsd", True, True, {"pixel_detail": False}),
    "tsd_lightsonly": ("tsd", False, False, {"translucency": False, "pixel_detail": False}),
    "preintegrated": ("preintegrated", True, True, None),
    "lambert": ("lambert", True, True, None),
    "lambert_lightsonly": ("lambert", False, False, None),
}


def _crop(scene, stem):
    import cycles_crops as cc

    got = cc.load_crop(cc.OUT, stem, "lips", scene, SIZE)
    if got is None:
        raise SystemExit(f"no current stored lips crop for {stem}")
    rgba, meta = got
    return cc.over_background(scene, rgba), rgba[..., 3] >= 0.999, meta["box"]


def geometry(a) -> None:
    import dermis
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.geometry.texture_space import texture_space_uvs
    from dermis.reference.render import camera_rays

    sc = dermis.load_scene(a.scene)
    o, d, tmax, _ = camera_rays(sc, (SIZE, SIZE), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    mesh, mm = sc.mesh, float(sc.mm_per_unit)
    pos = np.asarray(mesh.positions, np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    nrm = np.asarray(mesh.normals, np.float64)
    uvs = np.asarray(texture_space_uvs(mesh), np.float64)
    rc = RayCaster(pos, idx)
    light = sc.lights[0]
    L = -np.asarray(light.direction, float) / np.linalg.norm(light.direction)
    y0, y1 = a.rows
    for x in a.columns:
        pix = np.array([y * SIZE + x for y in range(y0, y1)])
        t, tri, bc = rc.closest_hit(o[pix], d[pix], 0.0, tmax[pix])
        bary = np.c_[1.0 - bc.sum(1), bc]
        p = o[pix] + d[pix] * t[:, None]
        n = np.einsum("nk,nkc->nc", bary, nrm[idx[tri]])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        uv = np.einsum("nk,nkc->nc", bary, uvs[idx[tri]]) * a.texels
        _, blocker, _ = rc.closest_hit(p + n * 1e-4, np.repeat(L[None], len(p), 0), 1e-4, np.inf)
        print(f"x = {x}: y, triangle, N.L, N.V, shadowed, uv (texels of {a.texels}), step from the row above (mm, texels)")
        for i, y in enumerate(range(y0, y1)):
            step = "" if i == 0 else \
                f"{np.linalg.norm(p[i] - p[i - 1]) * mm:5.2f} mm {np.linalg.norm(uv[i] - uv[i - 1]):6.2f} tx"
            print(f"  {y} {tri[i]:6d} {n[i] @ L:+.3f} {-(n[i] @ d[pix[i]]):+.3f} {'Y' if blocker[i] >= 0 else '.'} "
                  f"({uv[i, 0]:7.1f}, {uv[i, 1]:7.1f}) {step}")


def render(a) -> None:
    import dermis
    from dermis.renderer import Renderer

    out = {}
    _, _, (x0, y0, x1, y1) = _crop(dermis.load_scene(a.scene), Path(a.scene).stem)
    for name in a.variants:
        tech, bounce, ambient, opts = VARIANTS[name]
        sc = dermis.load_scene(a.scene)
        sc.material.pore_strength = 0.0  # Cycles has no procedural pores (cycles_crops.py score)
        sc.interreflection = bounce
        if not ambient:
            sc.environment.color = (0.0, 0.0, 0.0)
        t0 = time.perf_counter()
        with Renderer(sc, (SIZE, SIZE), irradiance_size=a.irradiance_size, shadow_size=a.shadow_size) as r:
            if opts:
                r.technique(tech, **opts)
            out[name] = r.render(tech).astype(np.float32)[y0:y1, x0:x1, :3]
        print(f"{name}: {time.perf_counter() - t0:.1f} s", flush=True)
    np.savez_compressed(a.out, **out)


def score(a) -> None:
    import dermis
    from dermis.reference.validate import metrics

    sc = dermis.load_scene(a.scene)
    ref, skin, (bx, by, _, _) = _crop(sc, Path(a.scene).stem)
    for f in a.npz:
        z = dict(np.load(f))
        for name, img in z.items():
            m, fmap = metrics(sc, ref, img, skin)
            s = f"{Path(f).stem:16s} {name:20s} crop {m['flip']:.4f}"
            for w, (x0, y0, x1, y1) in WINDOWS.items():
                win = (slice(y0 - by, y1 - by), slice(x0 - bx, x1 - bx))
                s += f"  {w} {fmap[win][skin[win]].mean():.4f}"
            print(s, flush=True)
        if a.columns:
            y0, y1 = a.rows
            for x in a.columns:  # 3 columns' mean, centred on x
                print(f"  x = {x}, luminance at y = {y0}..{y1 - 1}")
                for name, img in [("cycles", ref)] + list(z.items()):
                    col = img[y0 - by:y1 - by, x - bx - 1:x - bx + 2].mean(1) @ LUMINANCE
                    print(f"    {name:20s}", " ".join(f"{v:.3f}" for v in col))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="mode", required=True)
    ints = lambda s: [int(v) for v in s.split(",")]  # noqa: E731
    g = sub.add_parser("geometry")
    g.add_argument("scene")
    g.add_argument("--columns", type=ints, default=[380, 400])
    g.add_argument("--rows", type=ints, default=[642, 660])
    g.add_argument("--texels", type=int, default=1024)
    r = sub.add_parser("render")
    r.add_argument("scene")
    r.add_argument("out")
    r.add_argument("--irradiance-size", type=int, default=1024)
    r.add_argument("--shadow-size", type=int, default=2048)
    r.add_argument("--variants", type=lambda s: s.split(","), default=list(VARIANTS))
    s = sub.add_parser("score")
    s.add_argument("scene")
    s.add_argument("npz", nargs="+")
    s.add_argument("--columns", type=ints, default=None)
    s.add_argument("--rows", type=ints, default=[646, 656])
    a = ap.parse_args(argv)
    {"geometry": geometry, "render": render, "score": score}[a.mode](a)


if __name__ == "__main__":
    main()
