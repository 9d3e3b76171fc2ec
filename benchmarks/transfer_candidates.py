"""Gather/read-time candidates for the baked subsurface transfer at front-key's mouth line and lid crease, scored by
the numpy twin of what the pixels read (issue 12, round 24, branch mouth24; mouth23's suggestion: weight the transfer
by the point's own light against its taps', or read it per point in 3-D).

    PYTHONPATH=src python benchmarks/transfer_taps.py line /tmp/line.npz                               # the mouth line
    PYTHONPATH=src python benchmarks/transfer_taps.py line /tmp/lid.npz --x 440,470 --y 362,372        # the lid crease
    PYTHONPATH=src python benchmarks/transfer_candidates.py read /tmp/line.npz /tmp/lid.npz
    PYTHONPATH=src python benchmarks/transfer_candidates.py keyonly /tmp/keyonly.npz
    PYTHONPATH=src python benchmarks/transfer_taps.py walk /tmp/lid.npz --at-pixels --all-pixels --points 30 \
        --walks 8192 [--camera-view] > /tmp/walk_lid[_camera].log                                    # and the line's
    PYTHONPATH=src python benchmarks/transfer_candidates.py compare /tmp/keyonly.npz /tmp/lid.npz /tmp/walk_lid.log \
        /tmp/walk_lid_camera.log [--json J]

Per box (transfer_taps.py ``line``'s npz: the pixels' tent weights on the grid's texels, the bake points read, their
taps' weights and the irradiance I_3 they read, the GPU's grid equal to the numpy gather to ~1e-8), mean red over the
box's pixels, in the grid's units (tsd's irradiance map; x ~0.17 is the linear red the final pass adds at these
boxes): the cosine grid as read (tent over the points), the view term's deviation at the camera's view
(common/subsurface_transfer.glsl subsurface_transfer_view in numpy, the pixel's interpolated normal), and the read
under each candidate:
- ``own/taps clamp``: each point's transfer x min(1, I_3(point) / I_3 of its far taps, |w|-weighted) (the point's own
  light against its taps' light);
- ``far x own/taps``: the same factor on the far taps only;
- ``n.n^4``, ``gauss3d``: the tent re-weighted per point by its normal's agreement with the pixel's, or a 3-D Gaussian
  of the distance (a bilateral read: only the points on the pixel's own side of a crease).
``keyonly``: tsd at 768 px (irradiance 1024, pore_strength 0, as mouth_terms.py) under the key light alone (no bounce,
no environment), with and without the transfer: the transfer the key light's walk is the reference for, in linear red.
``compare``: per walked pixel, that rendered transfer against transfer_taps.py's walks at the pixel's own point
((walk - flat share) in units of the key's unit-intensity N.L, x SCALE = tsd's own linear red per unit N.L at the box's
lit pixels, E0 > 0.3, without the transfer: 0.467 / 0.456 at the line / lid), cosine views and the camera's ray. (The
renderer's own factor from a unit of excess to the image is ~0.56 at the lid: the grid-to-image factor ~0.235, from renders
with and without the transfer, times the map's I / N.L 2.40 at lit bake points; the difference between the two factors is
the exit's albedo^(1-mix) / pi against the skin's diffuse reflectance, not resolved here: read the ratios as +-20 %.)
The references (independent): transfer_taps.py ``walk --at-pixels [--all-pixels] [--camera-view]`` (fresh skin walks
at the pixels' own points less the flat kernel's share, cosine views or the camera's ray) and mouth_terms.py
``walks`` (the whole skin walk against tsd without the bounce).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
SIZE = 768


def _fresnel(c, eta):
    c = np.clip(c, 0.0, 1.0)
    s = np.sqrt(1.0 - c * c) / eta
    ct = np.sqrt(np.maximum(0.0, 1.0 - s * s))
    rs, rp = (c - eta * ct) / (c + eta * ct), (ct - eta * c) / (ct + eta * c)
    return 0.5 * (rs * rs + rp * rp)


def _refract(i, n, eta):  # GLSL refract(I, N, eta), rows
    d = (n * i).sum(-1)
    k = 1.0 - eta * eta * (1.0 - d * d)
    return eta * i - (eta * d + np.sqrt(np.maximum(k, 0.0)))[:, None] * n


def main(paths):
    import dermis
    from dermis.framing import framed_camera
    from dermis.reference.render import camera_rays
    from dermis.subsurface_transfer.bake import view_mean_constants
    from dermis.subsurface_transfer.store import find

    sc = dermis.load_scene(REPO / "examples" / "reference" / "front-key.toml")
    bake = find(sc)
    eta = float(bake.meta.get("index", 1.4))
    a0, a1 = view_mean_constants(eta)
    o, d, _, _ = camera_rays(sc, (SIZE, SIZE), 1, camera=framed_camera(sc.camera, sc.mesh, 1.0))
    for f in paths:
        z = np.load(f)
        used = z["used"]
        row = {u: i for i, u in enumerate(used)}
        Tn, tw, tI, bI = z["Tn"], z["tap_w"], z["tapI"], z["b_I"]
        V4 = (bake.tap_view[used] * tI[:, :, :, None]).sum(1)  # per point and channel sum_k (G, c)_k I_k
        npx = len(z["pix"])
        aw = np.abs(tw[:, 1:])
        far_I = (aw * tI[:, 1:]).sum(1) / np.maximum(aw.sum(1), 1e-12)
        vis = np.clip(bI / np.maximum(far_I, 1e-9), 0.0, 1.0)
        own = tw[:, 0] * tI[:, 0]
        cands = {"tent (shipped)": Tn, "own/taps clamp": Tn * vis, "far x own/taps": own + (Tn - own) * vis}
        pp, pn, bp, bn = z["pp"], z["pn"], z["b_pos"], z["b_n"]
        reads = {k: np.zeros((npx, 3)) for k in cands}
        bil = {k: (np.zeros((npx, 3)), np.zeros(npx)) for k in ("n.n^4", "gauss3d 0.5 mm", "gauss3d 1 mm")}
        v4 = np.zeros((npx, 3, 4))
        tot = np.zeros(npx)
        for (i, _, _), w, p in zip(z["wi"], z["ww"], z["pt"]):
            tot[i] += w
            if p < 0:
                continue
            j = row[p]
            v4[i] += w * V4[j]
            for k, T in cands.items():
                reads[k][i] += w * T[j]
            dist2 = np.sum((bp[j] - pp[i]) ** 2)
            for k, s in (("n.n^4", max(0.0, bn[j] @ pn[i]) ** 4), ("gauss3d 0.5 mm", np.exp(-0.5 * dist2 / 0.25)),
                         ("gauss3d 1 mm", np.exp(-0.5 * dist2))):
                bil[k][0][i] += w * s * Tn[j]
                bil[k][1][i] += w * s
        for k, (num, den) in bil.items():
            reads[k] = num / np.maximum(den, 1e-12)[:, None] * tot[:, None]
        dv = d[z["pix"]] / np.linalg.norm(d[z["pix"]], axis=1, keepdims=True)
        cv = (pn * -dv).sum(1)
        r = _refract(dv, pn, 1.0 / eta)
        seen = (1.0 - _fresnel(cv, eta))[:, None] * ((v4[:, :, :3] * r[:, None]).sum(-1) + v4[:, :, 3])
        dev = seen - (a0 * v4[:, :, 3] + a1 * (v4[:, :, :3] * pn[:, None]).sum(-1))
        lit = z["pE"] > 1e-3
        print(f"{Path(f).name}: {npx} px ({(~lit).sum()} in the key's shadow), N.V {cv.mean():.3f}, key E0 {z['pE'].mean():.3f}, "
              f"own I_3 red {z['pI'][:, 0].mean():.3f}; view deviation at the camera {dev[:, 0].mean():+.4f}")
        for k, v in reads.items():
            print(f"   {k:16s} cosine grid read {v[:, 0].mean():.4f} (/ shipped {v[:, 0].mean() / reads['tent (shipped)'][:, 0].mean():.3f})"
                  f", + view deviation {v[:, 0].mean() + dev[:, 0].mean():.4f}")


SCALE = 0.46  # tsd's linear red per unit key N.L at lit pixels without the transfer (keyonly: 0.467 line, 0.456 lid)


def keyonly(out) -> None:
    sys.path.insert(0, str(REPO / "benchmarks"))
    import mouth_terms
    from dermis.renderer import Renderer

    imgs = {}
    for name, off in (("with", False), ("without", True)):
        sc = mouth_terms._scene()
        sc.interreflection = False
        sc.environment.color = (0.0, 0.0, 0.0)
        with Renderer(sc, (SIZE, SIZE), irradiance_size=1024) as r:
            if off:
                r.technique("tsd").transfer.add = lambda *a, **k: False
            imgs[name] = np.asarray(r.render("tsd"))[..., :3].astype(np.float32)
    np.savez_compressed(out, **imgs)


def _walk_log(path):
    """transfer_taps.py walk's red rows: {pixel index: (E0, (walk - flat) in units of N.L)}."""
    import re

    red = Path(path).read_text().split("\nG:")[0]
    rows = {}
    for m in re.finditer(r"^\s+(\d+)\s+[\d.]+\s+([\d.]+)\s+\S+ \(\S+\)\s+\S+\s+\S+\s+(\S+)", red, re.M):
        e0 = float(m.group(2))
        rows[int(m.group(1))] = (e0, float(m.group(3)) * max(e0, 1e-3))  # the tool divides by max(E0, 1e-3)
    return rows


def compare(keyonly_npz, taps_npz, cosine_log, camera_log, json_out=None) -> dict:
    z = np.load(keyonly_npz)
    t = np.load(taps_npz)
    tr = (z["with"] - z["without"])[..., 0].reshape(-1)
    cos, cam = _walk_log(cosine_log), _walk_log(camera_log)
    pix = np.array(sorted(cos))
    box = tr[t["pix"]].mean()
    rep = {"box_pixels": int(len(t["pix"])), "rendered_box": float(box), "walked_pixels": int(len(pix)),
           "rendered": float(tr[pix].mean()), "walk_cosine": float(SCALE * np.mean([cos[p][1] for p in pix])),
           "walk_camera": float(SCALE * np.mean([cam[p][1] for p in pix])),
           "per_pixel": [[int(p % SIZE), int(p // SIZE), cos[p][0], float(tr[p]), SCALE * cos[p][1], SCALE * cam[p][1]]
                         for p in pix]}
    print(f"{Path(taps_npz).name}: key-only transfer, linear red: rendered {box:.4f} over the box ({len(t['pix'])} px), "
          f"{rep['rendered']:.4f} at the {len(pix)} walked px; walks there: cosine views {rep['walk_cosine']:.4f}, "
          f"camera ray {rep['walk_camera']:.4f}")
    if json_out:
        import json

        Path(json_out).write_text(json.dumps(rep, indent=1))
    return rep


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("read", "keyonly", "compare"))
    ap.add_argument("paths", nargs="+")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    if a.mode == "read":
        main(a.paths)
    elif a.mode == "keyonly":
        keyonly(a.paths[0])
    else:
        compare(*a.paths, json_out=a.json)
