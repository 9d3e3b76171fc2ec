"""``dermis validate --against cycles``: every technique against a converged Cycles render.

Per scene and per specular mode (on; off = rho_s 0 on both sides): Cycles (random-walk SSS through
dermis.blender.export) at two seeds, the samples doubled until the two differ by mean FLIP <=
``floor_target`` on the skin pixels (or ``max_spp`` is reached, reported as not converged); the
reference is the two seeds' mean. Each technique is scored with dermis.reference.validate.metrics
(mean FLIP, SSIM, relative RMSE on the skin pixels) plus the per-channel mean ratio, on the whole
skin and on regions derived from the mesh and lights (ray casts, dermis.geometry.raycast):

* ``shadow_edge``: front-facing pixels within 2 px of a cast-shadow boundary of any light (the nose
  shadow's penumbra in the front and side scenes);
* ``backlit_thin``: pixels facing away from a light whose body toward the light is thinner than
  BACKLIT_THICKNESS_MM (ears, nose wings, lit from behind).

Face parts, for a head facing +z with +y up (dermis's convention for heads), located from the nose
tip (the mesh's most forward vertex) with adult anthropometric offsets in millimetres (Farkas 1994,
"Anthropometry of the Head and Face": subnasale-stomion ~20 mm, stomion-lower lip ~ 10 mm,
endocanthion-endocanthion ~ 32 mm, exocanthion-exocanthion ~ 90 mm, eye level ~ 30-40 mm above
the nose tip):

* ``back_lit_ear``: backlit_thin more than EAR_LATERAL_MM to the side of the nose tip, at ear
  height and depth (EAR_BOX_MM: the ear canal lies ~ 90 mm behind the nose tip);
* ``nose_shadow_penumbra``: shadow_edge within the box around the nose;
* ``lips``: the box below the nose tip, the redder half of its albedo (lips are redder than the
  skin around them);
* ``eyelids``: the boxes around the eyes, front-facing points within EYE_DEPTH_MM of the nose tip's
  depth (the lids, not the deeper eye sockets' sides).
Scenes without a head-sized mesh (slabs, boxes) simply get no face regions (fewer than 8 pixels
are not scored).

The control row is Cycles itself without subsurface scattering (plain diffuse with the same
colour): a technique not closer than that has not shown its scattering helps. The seed-to-seed
floor (seed 0 vs seed 1, same metrics) stands beside every number.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from dermis.errors import DermisError

BACKLIT_THICKNESS_MM = 8.0
EDGE_PX = 2
EAR_LATERAL_MM = 55.0
EAR_BOX_MM = ((-45.0, 35.0), (-135.0, -50.0))  # (y range, z range) about the nose tip
NOSE_BOX_MM = ((-25.0, 25.0), (-25.0, 15.0))  # (x range, y range) about the nose tip
LIPS_BOX_MM = ((-30.0, 30.0), (-50.0, -15.0))
EYE_BOX_MM = ((12.0, 50.0), (15.0, 50.0))  # |x|, y about the nose tip
EYE_DEPTH_MM = 40.0


def _dilate(m, r):
    from scipy.ndimage import binary_dilation

    return binary_dilation(m, iterations=r)


def region_masks(scene, size, skin) -> dict:
    """{name: (H, W) bool} from ray casts of the camera's pixel centres against the mesh."""
    from dermis.framing import framed_camera
    from dermis.geometry.raycast import RayCaster
    from dermis.reference.render import camera_rays

    w, h = size
    m = scene.mesh
    pos = np.asarray(m.positions, np.float64)
    idx = np.asarray(m.indices, np.int64).reshape(-1, 3)
    bvh = RayCaster(pos, idx)
    o, d, tmax, _ = camera_rays(scene, size, 1, camera=framed_camera(scene.camera, m, w / h))
    t, tri, bc = bvh.closest_hit(o, d, 0.0, tmax)
    hit = tri >= 0
    P = o + d * np.where(hit, t, 0)[:, None]
    nrm = np.asarray(m.normals, np.float64)
    tt = np.where(hit, tri, 0)
    b1, b2 = bc[:, 0], bc[:, 1]
    N = (nrm[idx[tt, 0]] * (1 - b1 - b2)[:, None] + nrm[idx[tt, 1]] * b1[:, None] + nrm[idx[tt, 2]] * b2[:, None])
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-30)
    eps = 0.02 / float(scene.mm_per_unit)  # 0.02 mm off the surface
    edge = np.zeros((h, w), bool)
    backlit = np.zeros((h, w), bool)
    for L in scene.lights:
        if L.kind == "directional":
            Ld = -np.asarray(L.direction, np.float64) / np.linalg.norm(L.direction)
            Ld = np.broadcast_to(Ld, P.shape)
            far = np.inf
        else:
            v = np.asarray(L.position, np.float64) - P
            far = np.linalg.norm(v, axis=1)
            Ld = v / np.maximum(far, 1e-30)[:, None]
        ndl = (N * Ld).sum(axis=1)
        front = hit & (ndl > 0)
        occ = bvh.occluded(P + N * eps, Ld, 0.0, far, skip=tri)
        lit = (front & ~occ).reshape(h, w)
        shadow = (front & occ).reshape(h, w)
        edge |= _dilate(lit, EDGE_PX) & _dilate(shadow, EDGE_PX) & front.reshape(h, w)
        behind = hit & (ndl < 0)
        te, tre, _ = bvh.closest_hit(P - N * eps, Ld, 0.0, far)
        thin = behind & (tre >= 0) & (te * float(scene.mm_per_unit) < BACKLIT_THICKNESS_MM)
        backlit |= thin.reshape(h, w)
    out = {"shadow_edge": edge & skin, "backlit_thin": backlit & skin}
    out.update(face_regions(scene, P, hit, tri, bc, N, (h, w), out))
    return {k: v & skin for k, v in out.items()}


def face_regions(scene, P, hit, tri, bc, N, shape, base) -> dict:
    """back_lit_ear, nose_shadow_penumbra, lips, eyelids (see the module docstring); empty for a
    mesh smaller than a head."""
    m = scene.mesh
    mm = float(scene.mm_per_unit)
    pos = np.asarray(m.positions, np.float64)
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    if np.min(hi - lo) * mm < 100.0:  # not head-sized: no face parts
        return {}
    tip = pos[np.argmax(pos[:, 2])]
    rel = (P - tip) * mm  # mm from the nose tip
    x, y, z = rel[:, 0], rel[:, 1], rel[:, 2]

    def box(bx, by):
        return hit & (x >= bx[0]) & (x <= bx[1]) & (y >= by[0]) & (y <= by[1])

    ear = ((np.abs(x) > EAR_LATERAL_MM) & (y >= EAR_BOX_MM[0][0]) & (y <= EAR_BOX_MM[0][1])
           & (z >= EAR_BOX_MM[1][0]) & (z <= EAR_BOX_MM[1][1]))
    out = {"back_lit_ear": base["backlit_thin"] & ear.reshape(shape),
           "nose_shadow_penumbra": base["shadow_edge"] & box(*NOSE_BOX_MM).reshape(shape)}
    lips = box(*LIPS_BOX_MM) & (N[:, 2] > 0)
    if lips.any() and scene.material.albedo is not None:
        a = _albedo_at(scene, tri, bc)
        red = a[:, 0] / np.maximum(a[:, 1], 1e-4)
        lips &= red > np.median(red[lips])
    out["lips"] = lips.reshape(shape)
    ax = np.abs(x)
    eyes = hit & (ax >= EYE_BOX_MM[0][0]) & (ax <= EYE_BOX_MM[0][1]) & (y >= EYE_BOX_MM[1][0]) & (y <= EYE_BOX_MM[1][1])
    out["eyelids"] = (eyes & (z > -EYE_DEPTH_MM) & (N[:, 2] > 0.3)).reshape(shape)
    return out


def _albedo_at(scene, tri, bc) -> np.ndarray:
    """Albedo (linear) at the hit points: UVs interpolated, nearest texel (v up, row 0 = top)."""
    m = scene.mesh
    idx = np.asarray(m.indices, np.int64).reshape(-1, 3)
    uv = np.asarray(m.uvs, np.float64)
    t = np.where(tri >= 0, tri, 0)
    b1, b2 = bc[:, 0], bc[:, 1]
    u = uv[idx[t, 0]] * (1 - b1 - b2)[:, None] + uv[idx[t, 1]] * b1[:, None] + uv[idx[t, 2]] * b2[:, None]
    img = np.asarray(scene.material.albedo.data)
    hh, ww = img.shape[:2]
    col = np.clip((u[:, 0] % 1.0 * ww).astype(int), 0, ww - 1)
    row = np.clip(((1.0 - u[:, 1] % 1.0) * hh).astype(int), 0, hh - 1)
    return img[row, col, :3]


def _score(scene, ref, img, mask, regions):
    from dermis.reference.validate import metrics

    m, fmap = metrics(scene, ref, img, mask)
    m["mean_ratio"] = [float(x) for x in img[mask].mean(axis=0) / np.maximum(ref[mask].mean(axis=0), 1e-30)]
    m["regions"] = {}
    for name, r in regions.items():
        if r.sum() >= 8:
            m["regions"][name] = {"flip": float(fmap[r].mean()), "pixels": int(r.sum()),
                                  "mean_ratio": [float(x) for x in img[r].mean(axis=0) / np.maximum(ref[r].mean(axis=0), 1e-30)]}
    return m, fmap


ACCUMULATOR_VERSION = 1
"""Bumped when what a stored Cycles accumulation means changes (besides dermis.blender's sources)."""


_CYCLES_SCENE_INPUTS = ("mesh", "surfaces", "scale", "material_maps", "material_scalars", "light_geometry",
                        "lights", "environment", "environment_occlusion", "profile", "irradiance_size", "epoch")
"""The entries of dermis.invalidation.scene_inputs that a stored Cycles accumulation is keyed on."""


def _accumulator_key(scene, size, sss, specular) -> str:
    """What a stored accumulation depends on: the scene's content (mesh, maps, lights, profile,
    camera, output), the size, the Cycles set-up (dermis.blender's sources, bpy's version)."""
    import hashlib
    import inspect

    from dermis.blender import convert, export, render, require_bpy, sss as sss_mod
    from dermis.invalidation import scene_inputs

    inputs = scene_inputs(scene, irradiance_size=0, epoch=0)
    # A fixed list, not the whole dict: an input that dermis's real-time techniques gain later (and
    # Cycles never sees) must not make hours of stored samples stale. Same order, same repr as before.
    inputs = {name: inputs[name] for name in _CYCLES_SCENE_INPUTS}
    h = hashlib.sha1()
    for part in (ACCUMULATOR_VERSION, inputs, vars(scene.camera),
                 tuple(scene.output.background), float(scene.mm_per_unit), tuple(size), bool(sss), bool(specular),
                 require_bpy().app.version_string):
        h.update(repr(part).encode())
    for mod in (convert, export, render, sss_mod):
        h.update(inspect.getsource(mod).encode())
    return h.hexdigest()


class CyclesAccumulation:
    """Independent Cycles renders of one scene, averaged per stream: stream i takes seeds
    ``seed_base + i + streams * k`` for its k-th batch, so every sample is kept when the count
    grows (a 2N-spp stream is an N-spp stream plus a new N-spp batch, same variance as one 2N-spp
    render with independent samples). Stored in ``path`` (.npz, written atomically) under a key of
    the scene and set-up, so an interrupted or too-short run is resumed, never redone."""

    def __init__(self, scene, size, *, streams=2, sss=True, specular=True, seed_base=0, path=None):
        self.scene, self.size, self.streams, self.sss, self.specular = scene, tuple(size), streams, sss, specular
        self.seed_base, self.path = seed_base, Path(path) if path else None
        self.key = _accumulator_key(scene, size, sss, specular)
        w, h = self.size
        self.sums = np.zeros((streams, h, w, 4), np.float64)  # sum over batches of spp_k * image_k
        self.spp, self.batches, self.render_s, self.resumed_spp = 0, 0, 0.0, 0
        if self.path and self.path.is_file():
            try:
                with np.load(self.path) as z:
                    ok = str(z["key"]) == self.key and z["sums"].shape == self.sums.shape
                    if ok:
                        self.sums = z["sums"].astype(np.float64)
                        self.spp, self.batches = int(z["spp"]), int(z["batches"])
                        self.render_s, self.resumed_spp = float(z["render_s"]), int(z["spp"])
            except (OSError, ValueError, KeyError):
                pass  # unreadable: start over (it is rewritten after the first batch)

    def add(self, spp: int):
        """One more batch of ``spp`` samples in every stream."""
        from dermis.blender.render import render_cycles

        for i in range(self.streams):
            seed = self.seed_base + i + self.streams * self.batches
            img, st = render_cycles(self.scene, self.size, spp=spp, seed=seed, sss=self.sss,
                                    specular=self.specular, alpha=True)
            self.sums[i] += spp * img.astype(np.float64)
            self.render_s += st["build_s"] + st["render_s"]
        self.spp += int(spp)
        self.batches += 1
        if self.path:
            self._save()

    def _save(self):
        from dermis.fileio import atomic_write

        def write(tmp):
            with open(tmp, "wb") as f:
                np.savez(f, key=self.key, sums=self.sums, spp=self.spp, batches=self.batches,
                         render_s=self.render_s)

        self.path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(self.path, write)

    def image(self, i) -> np.ndarray:
        """Stream i's mean (H, W, 4) float32: linear radiance and coverage."""
        return (self.sums[i] / max(self.spp, 1)).astype(np.float32)


def converge(scene, size, *, spp=16, max_spp=1024, floor_target=0.01, sss=True, specular=True, echo=print,
             store=None):
    """Two seed streams, each doubled (a new batch as large as what it holds) until their mean FLIP
    on the skin <= floor_target or max_spp is reached; resumed from ``store`` (.npz) when given."""
    from dermis.reference.validate import metrics

    t0 = time.perf_counter()
    load0 = os.getloadavg()[0]
    acc = CyclesAccumulation(scene, size, sss=sss, specular=specular, path=store)
    if acc.spp:
        echo(f"  resumed {acc.spp} spp x 2 seeds from {store}")
    while True:
        if acc.spp == 0:
            acc.add(min(spp, max_spp))
        a, b = acc.image(0), acc.image(1)
        skin = (a[..., 3] >= 0.999) & (b[..., 3] >= 0.999)
        floor = metrics(scene, a[..., :3], b[..., :3], skin)[0]["flip"] if skin.any() else float("inf")
        echo(f"  cycles {acc.spp} spp x 2 seeds: seed-to-seed FLIP {floor:.4f} "
             f"({acc.render_s:.0f} s of Cycles, load {os.getloadavg()[0]:.1f})")
        if floor <= floor_target or acc.spp >= max_spp:
            break
        acc.add(min(acc.spp, max_spp - acc.spp))
    return a[..., :3], b[..., :3], skin, {
        "spp": acc.spp, "seeds": 2 * acc.batches, "floor_flip": floor, "converged": floor <= floor_target,
        "cycles_s": round(acc.render_s, 1), "total_s": round(time.perf_counter() - t0, 1),
        "resumed_spp": acc.resumed_spp, "load": [round(load0, 1), round(os.getloadavg()[0], 1)]}


def _check_cycles_pixel_filter(bsc, width):
    """The techniques are reconstructed with Blender's default film filter (Blackman-Harris,
    ``width`` px); the Cycles scene must use it, or the two sides estimate different pixels."""
    kind, size = bsc.cycles.pixel_filter_type, float(bsc.render.filter_size)
    if kind != "BLACKMAN_HARRIS" or abs(size - width) > 1e-6:
        raise DermisError(f"Cycles' pixel filter is {kind} {size} px; validate reproduces Blackman-Harris "
                          f"{width} px (Blender's default)")


def validate_cycles(scene_files, techniques, size, *, out_dir=None, spp=16, max_spp=1024, floor_target=0.01,
                    specular_modes=(True, False), supersample=4, echo=print) -> dict:
    """Every technique against Cycles on ``scene_files`` at ``size``. Each technique is rendered at
    ``supersample`` times the size and reconstructed with Cycles' own pixel filter
    (dermis.blender.pixel_filter), so that both sides estimate the same pixel integral; 1 compares
    the technique's own pixels (aliased edges and all)."""
    import dermis
    from dermis.blender import require_bpy
    from dermis.blender.pixel_filter import CYCLES_FILTER_WIDTH_PX, reconstruct
    from dermis.blender.sss import cycles_subsurface
    from dermis.reference.validate import _magma, _render, _save_png, display
    from dermis.techniques import technique_names

    if not (isinstance(supersample, int) and 1 <= supersample <= 16):
        raise DermisError(f"--supersample: {supersample!r} is not an integer from 1 to 16")
    require_bpy()
    available = technique_names()
    run = [t for t in techniques if t in available]
    for t in techniques:
        if t not in available:
            echo(f"note: technique '{t}' is not available in this build; skipped")
    out = Path(out_dir) if out_dir else None
    report = {"against": "cycles", "size": list(size), "floor_target": floor_target, "techniques": run, "scenes": {},
              "supersample": supersample,
              "regions": {"shadow_edge": f"front-facing pixels within {EDGE_PX} px of a cast-shadow boundary",
                          "backlit_thin": f"pixels facing away from a light, body toward it < {BACKLIT_THICKNESS_MM} mm",
                          "back_lit_ear": f"backlit_thin more than {EAR_LATERAL_MM} mm beside the nose tip, ear height/depth",
                          "nose_shadow_penumbra": "shadow_edge in the box around the nose",
                          "lips": "below the nose tip, the redder half of the albedo",
                          "eyelids": "the eye boxes, front-facing, within 40 mm of the nose tip's depth"},
              "notes": ["pore_strength = 0 on both sides", "Cycles: random-walk SSS fitted to the scene's profile "
                        "(dermis.blender.sss), occluded environment light, interreflections",
                        "control: Cycles without subsurface scattering",
                        f"techniques: rendered at {supersample}x the size, reconstructed with Cycles' pixel filter "
                        f"(Blackman-Harris, {CYCLES_FILTER_WIDTH_PX} px)",
                        "floor: seed 0 vs seed 1 at the final spp, same metrics; the reference is their mean"]}
    for f in scene_files:
        name = Path(f).stem
        for spec in specular_modes:
            sc = dermis.load_scene(f)
            sc.material.pore_strength = 0.0
            if not spec:
                sc.material.rho_s = 0.0
            key = f"{name}/{'spec' if spec else 'nospec'}"
            echo(f"[{key}] Cycles {size[0]}x{size[1]} ...")
            mode = "spec" if spec else "nospec"
            store = (out / name / f"cycles_{mode}_{size[0]}x{size[1]}.npz") if out else None
            a, b, skin, conv = converge(sc, size, spp=spp, max_spp=max_spp, floor_target=floor_target, specular=spec,
                                        echo=echo, store=store)
            if not skin.any():
                raise DermisError(f"{f}: the mesh covers no pixel fully; nothing to compare")
            ref = 0.5 * (a + b)
            _check_cycles_pixel_filter(require_bpy().context.scene, CYCLES_FILTER_WIDTH_PX)
            regions = region_masks(sc, size, skin)
            floor, _ = _score(sc, a, b, skin, regions)
            entry = {"source": str(f), "cycles": conv, "skin_pixels": int(skin.sum()),
                     "region_pixels": {k: int(v.sum()) for k, v in regions.items()},
                     "sss": {k: [float(x) for x in v] for k, v in vars(cycles_subsurface(sc)).items()
                             if isinstance(v, np.ndarray)},
                     "floor": floor, "techniques": {}}
            # the control: as many samples as one seed stream (its noise is in its score; the floor says how much)
            ctl = CyclesAccumulation(sc, size, streams=1, sss=False, specular=spec, seed_base=1 << 20,
                                     path=store.with_name(f"cycles_{mode}_nosss_{size[0]}x{size[1]}.npz") if store else None)
            if ctl.spp < conv["spp"]:
                ctl.add(conv["spp"] - ctl.spp)
            ctrl = ctl.image(0)[..., :3]
            conv["control_spp"] = ctl.spp
            rows = {"cycles-no-sss (control)": ctrl}
            for t in run:
                big, _ = _render(sc, t, (size[0] * supersample, size[1] * supersample))
                rows[t] = reconstruct(big[..., :3], supersample)
            strip = [("Cycles (SSS)", display(sc, ref), f"{conv['spp']} spp x 2")]
            for t, img in rows.items():
                m, fmap = _score(sc, ref, img, skin, regions)
                entry["techniques"][t] = m
                reg = "  ".join(f"{k} {v['flip']:.4f}" for k, v in m["regions"].items())
                echo(f"[{key}] {t:24s} FLIP {m['flip']:.4f} (floor {floor['flip']:.4f})  SSIM {m['ssim']:.4f}  "
                     f"relRMSE {m['rel_rmse']:.4f}  mean ratio {' '.join(f'{x:.3f}' for x in m['mean_ratio'])}  {reg}")
                label = "no SSS" if t.startswith("cycles-no-sss") else t
                strip += [(label, display(sc, img), f"FLIP {m['flip']:.3f}"), ("FLIP map", _magma(np.where(skin, fmap, 0.0)), "")]
            if out:
                d = out / name
                d.mkdir(parents=True, exist_ok=True)
                from dermis.compare import contact_sheet

                sheet = contact_sheet(strip, [f"{key}: seed-to-seed floor FLIP {floor['flip']:.3f}"])
                _save_png(d / f"{'spec' if spec else 'nospec'}_side_by_side.png", sheet.astype(np.float32) / 255.0)
                from dermis.images import write_exr

                write_exr(d / f"cycles_{'spec' if spec else 'nospec'}.exr", ref)
            report["scenes"][key] = entry
    report["largest"] = largest_differences(report)
    return report


FACE_REGIONS = ("back_lit_ear", "nose_shadow_penumbra", "lips", "eyelids")


def markdown_table(report, regions=None) -> str:
    """One row per scene x technique: each number with the seed-to-seed floor in brackets;
    ``regions``: the region columns (default: all the report has)."""
    regions = list(regions or report["regions"])
    head = ("| scene | technique | mean FLIP (floor) | SSIM (floor) | rel. RMSE (floor) | mean ratio R/G/B | "
            + " | ".join(f"FLIP {r} (floor)" for r in regions) + " | Cycles spp |")
    lines = [head, "|" + "---|" * (7 + len(regions))]  # one per header column
    for s, e in report["scenes"].items():
        fl = e["floor"]
        for t, m in e["techniques"].items():
            regs = []
            for r in regions:
                if r in m["regions"]:
                    regs.append(f"{m['regions'][r]['flip']:.4f} ({fl['regions'].get(r, {}).get('flip', float('nan')):.4f})")
                else:
                    regs.append("-")
            conv = e["cycles"]
            lines.append(f"| {s} | {t} | {m['flip']:.4f} ({fl['flip']:.4f}) | {m['ssim']:.4f} ({fl['ssim']:.4f}) | "
                         f"{m['rel_rmse']:.4f} ({fl['rel_rmse']:.4f}) | {'/'.join(f'{x:.3f}' for x in m['mean_ratio'])} | "
                         + " | ".join(regs) + f" | {conv['spp']}{'' if conv['converged'] else ' (not converged)'} |")
    return "\n".join(lines)


def largest_differences(report, regions=FACE_REGIONS) -> dict:
    """{technique: (scene, part, its FLIP, the control's FLIP there, the floor there, mean ratio)}: where
    (whole skin or a region, any scene) the technique is farthest from Cycles."""
    out = {}
    for s, e in report["scenes"].items():
        ctrl = next((m for t, m in e["techniques"].items() if t.startswith("cycles-no-sss")), None)
        for t, m in e["techniques"].items():
            parts = [("skin", m["flip"], m["mean_ratio"], ctrl["flip"] if ctrl else None, e["floor"]["flip"])]
            for r in regions:
                if r in m["regions"]:
                    c = ctrl["regions"].get(r, {}).get("flip") if ctrl else None
                    parts.append((r, m["regions"][r]["flip"], m["regions"][r]["mean_ratio"], c,
                                  e["floor"]["regions"].get(r, {}).get("flip")))
            for part, f, ratio, c, fl in parts:
                if t not in out or f > out[t]["flip"]:
                    out[t] = {"scene": s, "part": part, "flip": f, "control_flip": c, "floor_flip": fl,
                              "mean_ratio": ratio}
    return out
