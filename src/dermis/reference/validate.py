"""Fidelity of the real-time techniques against the offline reference (``dermis validate``).

For each scene: render the reference (render.render_reference) and every requested technique
(dermis.Renderer, same size, 4x MSAA), then measure on the SKIN pixels - those every sub-pixel
reference ray hits (coverage 1), so silhouette pixels, whose MSAA coverage differs, do not count:

* mean FLIP (Andersson et al. 2020, the ``flip-evaluator`` package, LDR mode, default 67 pixels
  per degree) between the display images (the scene's exposure and tone map, sRGB encoded);
* SSIM (Wang et al. 2004, skimage.metrics.structural_similarity, 7x7 window, on the display
  images, averaged over the three channels and the skin pixels);
* relative RMSE on linear radiance: sqrt(sum (t - r)^2 / sum r^2) over the skin pixels.

Error attribution: every technique is also measured against the reference with
``paths = "tissue"`` (no light across the air gap of creases: eyelids, lips, folds), which says
how much of its error is the crease semantics of the 3-D-distance model; for ``tsd``, the same
metric after toggling one part of the pipeline at a time (irradiance texture resolution,
shadow-map resolution, PCF softness, multi-resolution blurs, translucency), and FLIP
split between pixels near the UV seams and the rest.
Both sides render the same material with ``pore_strength = 0`` (the reference has no procedural
pore normals) and the same SH environment light, occluded by the visible fraction of its irradiance
(baked per vertex in the techniques, ray cast per sample point in the reference) unless the
scene sets [environment] occlusion = false.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from dermis.errors import DermisError

SEAM_BAND_SIGMAS = 2.0
"""Pixels within this many widest-Gaussian sigmas (3-D distance) of a UV seam form the seam band."""


def default_scene_files() -> list[Path]:
    """examples/reference/*.toml of the source tree (the reference scene set)."""
    root = Path(__file__).resolve().parents[3] / "examples" / "reference"
    files = sorted(root.glob("*.toml"))
    if not files:
        raise DermisError(f"no reference scenes found in {root} (pass scene files explicitly)")
    return files


def display(scene, linear):
    from dermis.output import output_transform

    o = scene.output
    return output_transform(linear, o.exposure, o.tonemap)


def metrics(scene, reference, test, mask) -> tuple[dict, np.ndarray]:
    """({"flip", "ssim", "rel_rmse"} on ``mask``, the FLIP error map (H, W))."""
    import flip_evaluator as flip
    from skimage.metrics import structural_similarity

    if not mask.any():
        raise DermisError(f"{scene.source}: the reference covers no pixel fully; nothing to compare")
    r_disp = np.ascontiguousarray(display(scene, reference), np.float32)
    t_disp = np.ascontiguousarray(display(scene, test), np.float32)
    fmap, _, _ = flip.evaluate(r_disp, t_disp, "LDR", applyMagma=False)
    fmap = np.asarray(fmap, np.float32).reshape(mask.shape)
    _, smap = structural_similarity(r_disp, t_disp, channel_axis=2, data_range=1.0, full=True)
    d = (test.astype(np.float64) - reference)[mask]
    rel = float(np.sqrt((d ** 2).sum() / max((reference[mask].astype(np.float64) ** 2).sum(), 1e-300)))
    return {"flip": float(fmap[mask].mean()), "ssim": float(smap[mask].mean()), "rel_rmse": rel}, fmap


def seam_vertices_mm(scene) -> np.ndarray:
    """Positions (mm) of vertices on a UV seam: a position that carries more than one UV."""
    m = scene.mesh
    key = np.round(np.asarray(m.positions, np.float64) * 1e5).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    uv_key = np.round(np.asarray(m.uvs, np.float64) * 1e6).astype(np.int64)
    order = np.lexsort((uv_key[:, 1], uv_key[:, 0], inv))
    g, u = inv[order], uv_key[order]
    differs = (g[1:] == g[:-1]) & np.any(u[1:] != u[:-1], axis=1)
    seam_groups = np.unique(g[1:][differs])
    on_seam = np.isin(inv, seam_groups)
    return np.asarray(m.positions, np.float64)[on_seam] * float(scene.mm_per_unit)


def seam_band(scene, positions_mm, mask) -> np.ndarray:
    """Skin pixels whose visible point lies within SEAM_BAND_SIGMAS widest sigmas of a seam vertex."""
    from scipy.spatial import cKDTree

    seams = seam_vertices_mm(scene)
    band = np.zeros_like(mask)
    if len(seams) == 0:
        return band
    radius = SEAM_BAND_SIGMAS * float(np.sqrt(np.max(scene.profile.variances_mm2)))
    d, _ = cKDTree(seams).query(positions_mm[mask], k=1, distance_upper_bound=radius)
    band[mask] = np.isfinite(d)
    return band


def _render(scene, name, size, **renderer_options):
    from dermis.renderer import Renderer

    t0 = time.perf_counter()
    tweak = renderer_options.pop("tweak", None)
    with Renderer(scene, size, **renderer_options) as r:
        if tweak:
            tweak(r)
        img = r.render(name)
    return img, time.perf_counter() - t0


def attribution_toggles():
    """(name, what it measures, renderer options, scene edit or None) for tsd."""

    def soft0(scene):
        for L in scene.lights:
            L.shadow_softness = 0.0

    def multires_off(r):
        r.technique("tsd", multires=False)

    def translucency_off(r):
        r.technique("tsd", translucency=False)

    return [
        ("irradiance_2048", "irradiance texture 2048^2 instead of 1024^2 (texture-space resolution, stretch)",
         {"irradiance_size": 2048}, None),
        ("shadow_4096", "shadow-map tiles 4096^2 instead of 1024^2 (shadow resolution)", {"shadow_size": 4096}, None),
        ("pcf_off", "shadow_softness = 0: one bilinear compare instead of the PCF disc (shadow softening)", {}, soft0),
        ("multires_off", "every blur at full resolution (multi-resolution blurs)", {"tweak": multires_off}, None),
        ("translucency_off", "no translucency (light through thin parts)", {"tweak": translucency_off}, None),
    ]


def _save_png(path, img):
    from dermis.images import write_png

    write_png(path, img)


def _magma(fmap):
    import matplotlib

    return matplotlib.colormaps["magma"](np.clip(fmap, 0, 1))[:, :, :3].astype(np.float32)


def validate(scene_files, techniques, size, *, out_dir=None, spp=4, spacing_mm=None, seed=0, attribution=True,
             progress=True, echo=print) -> dict:
    """Run the comparison; returns the report (a dict ready for JSON). Images go to ``out_dir``."""
    import dermis
    from dermis.reference.render import render_reference
    from dermis.techniques import technique_names

    available = technique_names()
    skipped = [t for t in techniques if t not in available]
    run = [t for t in techniques if t in available]
    for t in skipped:
        echo(f"note: technique '{t}' is not available in this build; skipped (available: {', '.join(available)})")
    out = Path(out_dir) if out_dir else None
    report = {"size": list(size), "spp": spp, "techniques": run, "skipped_techniques": skipped,
              "mask": "pixels whose every reference sub-pixel ray hits the mesh",
              "metrics": {"flip": "mean FLIP (flip-evaluator, LDR, 67 ppd) of the display images, lower is better",
                          "ssim": "mean SSIM of the display images (skimage, 7x7), higher is better",
                          "rel_rmse": "sqrt(sum (t - r)^2 / sum r^2) of linear radiance, lower is better"},
              "notes": ["pore_strength = 0 on both sides (the reference has no procedural pore normals)",
                        "environment light: SH irradiance times its visible fraction (techniques: per-vertex bake; "
                        "reference: ray cast per sample point), unless [environment] occlusion = false",
                        "reference shadows are exact ray casts (hard); techniques use PCF shadow maps",
                        "interreflection off on both sides (the reference has none; the techniques' one bounce is "
                        "measured against Cycles: validate --against cycles)",
                        "directional albedo off in tsd, ssss and preintegrated (the reference's exit is Lambertian)"],
              "scenes": {}}
    for f in scene_files:
        scene = dermis.load_scene(f)
        scene.material.pore_strength = 0.0
        scene.interreflection = False  # the reference has no interreflection: compare like with like
        scene.directional_albedo = False  # its exit is Lambertian (a diffusion profile): like with like
        name = Path(f).stem
        echo(f"[{name}] reference {size[0]}x{size[1]} ...")
        ref = render_reference(scene, size, spp=spp, min_spacing_mm=spacing_mm, seed=seed, progress=progress)
        mask = ref.coverage >= 1.0
        entry = {"source": str(f), "skin_pixels": int(mask.sum()),
                 "reference": {k: ref.stats[k] for k in ("samples", "visible_points", "min_spacing_mm", "pixel_footprint_mm",
                                                         "pairs", "total_s", "timings_s") if k in ref.stats},
                 "techniques": {}}
        sdir = None
        if out:
            sdir = out / name
            sdir.mkdir(parents=True, exist_ok=True)
            _save_png(sdir / "reference.png", display(scene, ref.image))
            from dermis.images import write_exr

            write_exr(sdir / "reference.exr", ref.image)
        band = seam_band(scene, ref.positions_mm, mask) if ref.positions_mm is not None else np.zeros_like(mask)
        entry["seam_band_pixels"] = int(band.sum())
        for t in run:
            img, secs = _render(scene, t, size)
            m, fmap = metrics(scene, ref.image, img, mask)
            m["render_s"] = round(secs, 3)
            if band.any() and (mask & ~band).any():
                m["flip_seam_band"] = float(fmap[band].mean())
                m["flip_elsewhere"] = float(fmap[mask & ~band].mean())
            entry["techniques"][t] = m
            echo(f"[{name}] {t:14s} FLIP {m['flip']:.4f}  SSIM {m['ssim']:.4f}  relRMSE {m['rel_rmse']:.4f}  ({secs:.1f} s)")
            if sdir:
                _save_png(sdir / f"{t}.png", display(scene, img))
                shown = np.where(mask, fmap, 0.0)
                _save_png(sdir / f"{t}_flip.png", _magma(shown))
        if attribution:
            # the same techniques against the reference whose light does not cross air gaps
            echo(f"[{name}] reference (paths = tissue) ...")
            ref_t = render_reference(scene, size, spp=spp, min_spacing_mm=spacing_mm, seed=seed, progress=progress,
                                     paths="tissue")
            entry["reference_tissue_paths"] = {"flip_straight_vs_tissue": metrics(scene, ref.image, ref_t.image, mask)[0]}
            for t in run:
                img, _ = _render(scene, t, size)
                m, _ = metrics(scene, ref_t.image, img, mask)
                entry["techniques"][t]["vs_tissue_paths"] = m
                echo(f"[{name}] {t:14s} vs tissue-path reference: FLIP {m['flip']:.4f}  SSIM {m['ssim']:.4f}  "
                     f"relRMSE {m['rel_rmse']:.4f}")
        if attribution and "tsd" in run:
            base = entry["techniques"]["tsd"]["flip"]
            att = {}
            for key, what, opts, edit in attribution_toggles():
                sc = dermis.load_scene(f)
                sc.material.pore_strength = 0.0
                sc.interreflection = False
                sc.directional_albedo = False
                if edit:
                    edit(sc)
                img, secs = _render(sc, "tsd", size, **dict(opts))
                m, _ = metrics(sc, ref.image, img, mask)
                att[key] = {"what": what, **m, "flip_change": m["flip"] - base, "render_s": round(secs, 3)}
                echo(f"[{name}] tsd {key:16s} FLIP {m['flip']:.4f} ({m['flip'] - base:+.4f})")
            entry["tsd_attribution"] = att
        report["scenes"][name] = entry
    return report


def markdown_table(report) -> str:
    """The report's per-scene, per-technique numbers as a Markdown table."""
    def f(x):
        return "-" if x is None else f"{x:.4f}"

    lines = ["| scene | technique | mean FLIP | SSIM | rel. RMSE | FLIP vs tissue-path ref. | FLIP near seams | FLIP elsewhere |",
             "|---|---|---|---|---|---|---|---|"]
    for s, e in report["scenes"].items():
        for t, m in e["techniques"].items():
            lines.append(f"| {s} | {t} | {m['flip']:.4f} | {m['ssim']:.4f} | {m['rel_rmse']:.4f} | "
                         f"{f(m.get('vs_tissue_paths', {}).get('flip'))} | {f(m.get('flip_seam_band'))} | "
                         f"{f(m.get('flip_elsewhere'))} |")
    return "\n".join(lines)
