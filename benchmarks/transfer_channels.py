"""Is the baked subsurface transfer's magnitude right PER CHANNEL (issue 12, round 17 transfer17)?

At a 768 px crop (benchmarks/cycles/crops: the stored Cycles crop's window), on the band of skin where tsd's
transfer adds > 2 % red (rows17's band) and on the rest (|transfer| <= 0.2 % red), per channel R G B:

1. the image: tsd over tsd without the transfer's add pass, less 1 (what the runtime adds), and Cycles' band over
   its rest against tsd-without-the-transfer's band over its rest, less 1 (what the reference adds beyond the flat
   profile; rows17's "+2.8 / +2.4 / +2.2 %");
2. at ``--points`` band pixels' visible points (camera rays, Embree; benchmarks/row_pixels.surface_points): the
   shipped bake's per-point total (the nearest bake point within 2 texels: sum of the taps, per unit uniform
   irradiance) and the transfer's own estimator walked afresh there (bake_transfer(points=...), the skin walk,
   another seed, ``--walks`` walks; its standard error from the per-walk tallies), both per channel;
3. the runtime's own prediction at those pixels: the gather (numpy twin, dermis.gl.subsurface_transfer.transfer_numpy)
   of the shipped bake's taps over tsd's blurred irradiance map I_3 (read back from the renderer), divided by tsd's
   diffused irradiance without the transfer at the same texel: what the add pass should add, per channel, if it is
   applied as the final pass says ((D k(N.V) + T + T_geo) albedo^(1-mix) / pi), against the image's share (1).

    PYTHONPATH=src python benchmarks/transfer_channels.py environment spec lips [--points 300 --walks 512]
    PYTHONPATH=src python benchmarks/transfer_channels.py front-key nospec nose

Also prints the bake's media (meta) against skin_media of the scene's profile and mean albedo now; ``--local-albedo``:
the walk in the medium of the band's own albedo (the map at the points; the bake uses the mean skin's); ``--media``:
band and rest walks in the skin walk and Cycles' medium (dermis.blender.sss.cycles_subsurface), cosine and view entry.
About 1 min (400 s with --media --local-albedo) at load 2-4.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

CH = "RGB"


def _fmt(v, p="+.4f"):
    return " ".join(format(float(x), p) for x in v)


def media_check(sc, bake):
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer import bake as B

    albedo = np.asarray(mean_skin_albedo(sc.material), np.float64)
    now = B.skin_media(sc.profile, albedo)
    m = bake.meta
    print(f"  bake meta: albedo {_fmt(m['albedo'], '.4f')}, mfp {_fmt(m['mean_free_path_mm'], '.4f')} mm, "
          f"ss albedo {_fmt(m['single_scattering_albedo'], '.5f')}, R_flat {_fmt(m['flat_reflectance'], '.4f')}, "
          f"F_flat(1 mm) {_fmt(m['flat_within_min_surface'], '.4f')}")
    print(f"  now      : albedo {_fmt(albedo, '.4f')}, mfp {_fmt([x.mean_free_path_mm for x in now], '.4f')} mm, "
          f"ss albedo {_fmt([x.single_scattering_albedo for x in now], '.5f')}")
    return albedo, now


def study(name, mode, landmark, n_points, walks, seed, size=768, media_runs=False, local_albedo=False):
    import cycles_crops as C
    from row_pixels import surface_points
    from scipy.spatial import cKDTree

    import dermis
    from dermis.gl.subsurface_transfer import transfer_numpy
    from dermis.renderer import Renderer
    from dermis.subsurface_transfer import bake as B
    from dermis.subsurface_transfer.store import find

    sc = dermis.load_scene(C.SCENES[name])
    if mode == "nospec":
        sc.material.rho_s = 0.0
    got = C.load_crop(C.OUT, name, landmark, sc, size, mode == "spec")
    if got is None:
        raise SystemExit(f"no current Cycles crop {name}:{landmark} ({mode})")
    rgba, meta = got
    sc.material.pore_strength = 0.0
    x0, y0, x1, y1 = meta["box"]
    skin = rgba[..., 3] >= 0.999
    ref = C.over_background(sc, rgba)
    bake = find(sc)
    print(f"===== {name}/{mode} {landmark}: crop {meta['box']}")
    albedo, media = media_check(sc, bake)
    t0 = time.time()
    grab = {}
    with Renderer(sc, (size, size), irradiance_size=1024) as r:
        img = r.render("tsd")[..., :3]
    with Renderer(sc, (size, size), irradiance_size=1024) as r:
        tech = r.technique("tsd")
        orig_gather = tech.transfer.gather

        def spy(irradiance, mipmaps=True):  # the map the taps read (premultiplied), as the gather sees it
            a = np.frombuffer(irradiance.read(), np.float32 if irradiance.dtype == "f4" else np.float16)
            grab["I"] = a.reshape(irradiance.size[1], irradiance.size[0], irradiance.components).astype(np.float64)
            return orig_gather(irradiance, mipmaps)

        tech.transfer.gather = spy
        r.render("tsd")  # the gather's input only
    with Renderer(sc, (size, size), irradiance_size=1024) as r:  # the tweak before the first render (cached products)
        r.technique("tsd").transfer.add = lambda *a, **k: False
        no = r.render("tsd")[..., :3]
    print(f"  renders {time.time() - t0:.0f} s")
    tr = (img - no) / np.maximum(no, 1e-6)
    full_skin = np.zeros(img.shape[:2], bool)
    full_skin[y0:y1, x0:x1] = skin
    band, rest = full_skin & (tr[..., 0] > 0.02), full_skin & (np.abs(tr[..., 0]) <= 0.002)
    refF = np.zeros_like(img)
    refF[y0:y1, x0:x1] = ref
    print(f"  skin {full_skin.sum()} px, band {band.sum()}, rest {rest.sum()}")
    cyc = (refF[band].mean(0) / refF[rest].mean(0)) / (no[band].mean(0) / no[rest].mean(0)) - 1.0
    print(f"  (1) image, band: tsd / tsd-without - 1 (mean of the ratio) {_fmt(tr[band].mean(0))}; "
          f"(sum ratio) {_fmt(img[band].sum(0) / no[band].sum(0) - 1)}")
    print(f"      Cycles' band/rest over tsd-without's band/rest - 1 {_fmt(cyc)}; tsd's {_fmt((img[band].mean(0) / img[rest].mean(0)) / (no[band].mean(0) / no[rest].mean(0)) - 1.0)}")
    print(f"      band to Cycles: tsd {_fmt(img[band].mean(0) / refF[band].mean(0), '.3f')}, without {_fmt(no[band].mean(0) / refF[band].mean(0), '.3f')}; "
          f"rest: {_fmt(no[rest].mean(0) / refF[rest].mean(0), '.3f')}")
    # (2) sampled band pixels: shipped bake, fresh walk
    rng = np.random.default_rng(seed)
    ys, xs = np.nonzero(band)
    pick = rng.choice(len(ys), min(n_points, len(ys)), replace=False)
    mask = np.zeros(band.shape, bool)
    mask[ys[pick], xs[pick]] = True
    pts, view = surface_points(sc, mask)
    order = np.nonzero(mask.reshape(-1))[0]
    py, px = np.divmod(order, mask.shape[1])
    share = tr[py, px]
    grid = int(bake.meta.get("grid", 512))
    dist, j = cKDTree(np.asarray(bake.point_uv, np.float64)).query(pts.uv)
    cov = dist < 2.0 / grid
    print(f"  (2) {len(order)} band pixels, {cov.sum()} with a bake point within 2 texels; image share there {_fmt(share[cov].mean(0))}")
    shipped = bake.total[j]
    print(f"      shipped bake total (uniform light)  {_fmt(shipped[cov].mean(0))}  G/R {shipped[cov, 1].mean() / shipped[cov, 0].mean():.3f} "
          f"B/R {shipped[cov, 2].mean() / shipped[cov, 0].mean():.3f}")
    if bake.excess is not None:  # the walks' own per-point estimate, before bake.denoise averaged the own tap over 1 mm
        raw = bake.excess[j].sum(2)
        print(f"      shipped bake before its denoise (the walks' own)  {_fmt(raw[cov].mean(0))}")
    t0 = time.time()
    kernels = [B.flat_kernel(m) for m in media]
    fresh = B.bake_transfer(sc.mesh, float(sc.mm_per_unit), sc.profile, albedo, points=pts, walks=walks, media=media,
                            kernels=kernels, seed=seed)
    se_pt = np.sqrt(np.maximum(fresh.excess_cov[..., 0] + fresh.excess_cov[..., 1] + 2.0 * fresh.excess_cov[..., 2], 0.0))
    f = fresh.total[cov]
    se = np.sqrt((se_pt[cov] ** 2).sum(0)) / cov.sum()
    print(f"      fresh walk ({walks} walks, seed {seed}, {time.time() - t0:.0f} s) {_fmt(f.mean(0))} +- {_fmt(se, '.4f')}  "
          f"G/R {f[:, 1].mean() / f[:, 0].mean():.3f} B/R {f[:, 2].mean() / f[:, 0].mean():.3f}")
    print(f"      same-facing transport / R_flat (fresh) {_fmt(fresh.kept[cov].mean(0), '.4f')}")
    # (3) the runtime's prediction: the gather over the map it reads, over the diffused irradiance without it
    I = grab.get("I")
    if I is not None:
        pred_T = transfer_numpy(bake, I)
        print(f"      gathered T_geo per bake point (numpy twin of the GL gather) at the sampled points {_fmt(pred_T[j[cov]].mean(0))} "
              f"(irradiance map units); over the point's own I_3 {_fmt((pred_T[j[cov]] / np.maximum(_at(I, pts.uv[cov]), 1e-9)).mean(0))}")
    if local_albedo:
        a = albedo_at_pixels(sc, mask)
        lm = B.skin_media(sc.profile, a)
        lk = [B.flat_kernel(m) for m in lm]
        bl = B.bake_transfer(sc.mesh, float(sc.mm_per_unit), sc.profile, a, points=pts, walks=walks, media=lm, kernels=lk,
                             seed=seed)
        print(f"      the band's own albedo (map at the points) {_fmt(a, '.4f')} ({_fmt(a / albedo, '.3f')} of the mean skin): "
              f"medium mfp {_fmt([m.mean_free_path_mm for m in lm], '.4f')} mm, ss albedo "
              f"{_fmt([m.single_scattering_albedo for m in lm], '.5f')}; fresh walk {_fmt(bl.total[cov].mean(0))}")
    if media_runs:
        _band_rest_walks(sc, albedo, media, kernels, band, rest, n_points, walks, seed, refF, no, img)
    return dict(share=share[cov].mean(0), shipped=shipped[cov].mean(0), fresh=f.mean(0), fresh_se=se, cycles=cyc,
                image=tr[band].mean(0))


def cycles_media(sc):
    """Cycles' walk per channel as dermis models it (index-matched, ends at its first surface hit): the mean free
    path Cycles' Subsurface Radius gives (dermis.blender.sss.cycles_subsurface: radius / (4 pi), as round 7's
    0.735 / 0.247 mm) and Chiang et al. 2016's albedo remap of the base colour (benchmarks/ear_translucency.py)."""
    from ear_translucency import chiang_alpha

    from dermis.blender.sss import cycles_subsurface
    from dermis.reference.random_walk import WalkMedium

    cs = cycles_subsurface(sc)
    mfp = np.asarray(cs.radius_mm, np.float64) / (4.0 * np.pi)
    base = np.clip(cs.albedo * cs.base_gain, 0.0, 1.0)
    return tuple(WalkMedium(float(mfp[c]), float(chiang_alpha(base[c])), "fresnel", 1.0) for c in range(3))


def _band_rest_walks(sc, albedo, skin, skin_kernels, band, rest, n, walks, seed, ref, no, img):
    """The transfer's estimator (and the walk's same-facing transport / its flat reflectance) at n band and n rest
    pixels' visible points, in the skin walk and Cycles' medium, cosine entry and along the camera ray (Cycles'
    walk starts along the view): band over rest per channel, against the crop's band over rest."""
    from row_pixels import surface_points, walks_along

    from dermis.subsurface_transfer import bake as B

    cyc = cycles_media(sc)
    print(f"  Cycles' medium: mfp {_fmt([m.mean_free_path_mm for m in cyc], '.4f')} mm, ss albedo "
          f"{_fmt([m.single_scattering_albedo for m in cyc], '.4f')}")
    cyc_kernels = [B.flat_kernel(m) for m in cyc]
    rng = np.random.default_rng(seed + 1)
    sets = {}
    for label, m in (("band", band), ("rest", rest)):
        ys, xs = np.nonzero(m)
        pick = rng.choice(len(ys), min(n, len(ys)), replace=False)
        mk = np.zeros(m.shape, bool)
        mk[ys[pick], xs[pick]] = True
        sets[label] = surface_points(sc, mk)
    out = {}
    for mlabel, media, kernels in (("skin", skin, skin_kernels), ("cycles", cyc, cyc_kernels)):
        for along_view in (False, True):
            for label, (pts, view) in sets.items():
                with walks_along(B, pts, view if along_view else None):
                    bk = B.bake_transfer(sc.mesh, float(sc.mm_per_unit), sc.profile, albedo, points=pts, walks=walks,
                                         media=media, kernels=kernels, seed=seed + 5)
                out[(mlabel, along_view, label)] = (bk.total.mean(0), bk.kept.mean(0))
            (tb, kb), (tr_, kr) = out[(mlabel, along_view, "band")], out[(mlabel, along_view, "rest")]
            print(f"    {mlabel:6s} {'view' if along_view else 'cosine'} entry: excess band {_fmt(tb)}, rest {_fmt(tr_)}, "
                  f"band - rest {_fmt(tb - tr_)} | same-facing / flat band {_fmt(kb, '.4f')}, rest {_fmt(kr, '.4f')}, "
                  f"band / rest - 1 {_fmt(kb / kr - 1.0)}")


def albedo_at_pixels(sc, mask) -> np.ndarray:
    """The albedo map's mean (times the scene's albedo scale) at the visible points of ``mask``'s pixels (the mesh
    uvs of the same camera rays as row_pixels.surface_points; image row 0 = v 1, as the rasteriser's)."""
    from dermis.geometry.raycast import RayCaster
    from dermis.images import as_rgb
    from dermis.reference.render import camera_rays
    from dermis.scene.model import mean_skin_albedo, skin_albedo_scale

    if sc.material.albedo is None:
        return np.asarray(mean_skin_albedo(sc.material), np.float64)
    mesh = sc.mesh
    o, d, tmax, _ = camera_rays(sc, mask.shape[::-1], 1)
    pix = np.nonzero(mask.reshape(-1))[0]
    pos = np.asarray(mesh.positions, np.float64)
    idx = np.asarray(mesh.indices, np.int64).reshape(-1, 3)
    _, tri, bc = RayCaster(pos, idx).closest_hit(o[pix], d[pix], 0.0, tmax[pix])
    uv = np.einsum("nk,nkc->nc", np.c_[1.0 - bc.sum(1), bc], np.asarray(mesh.uvs, np.float64)[idx[tri]])
    tex = as_rgb(sc.material.albedo.data).astype(np.float64)
    h, w = tex.shape[:2]
    a = tex[np.clip(((1.0 - uv[:, 1]) * h).astype(int), 0, h - 1), np.clip((uv[:, 0] * w).astype(int), 0, w - 1)]
    return a.mean(0) * skin_albedo_scale(sc)


def _at(I, uv):
    """The premultiplied map's colour (rgb / coverage) at uv, nearest texel (row 0 = v 0)."""
    h, w = I.shape[:2]
    x = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    y = np.clip((uv[:, 1] * h).astype(int), 0, h - 1)
    c = I[y, x]
    return c[:, :3] / np.maximum(c[:, 3:4], 1e-9)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("mode", choices=("spec", "nospec"))
    ap.add_argument("landmark")
    ap.add_argument("--points", type=int, default=300)
    ap.add_argument("--walks", type=int, default=512)
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--media", action="store_true", help="also band vs rest walks, skin and Cycles' medium, both entries")
    ap.add_argument("--local-albedo", action="store_true", help="also the walk in the medium of the band's own albedo")
    a = ap.parse_args(argv)
    study(a.scene, a.mode, a.landmark, a.points, a.walks, a.seed, media_runs=a.media, local_albedo=a.local_albedo)


if __name__ == "__main__":
    main()
