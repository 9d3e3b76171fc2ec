"""The offline reference renderer: the same skin model as the real-time techniques, integrated
directly over the surface instead of in texture or screen space.

For each pixel, camera rays (dermis.camera's matrices; ``spp`` sub-pixel positions, 4 = the
standard 4x MSAA pattern the real-time renderer resolves) find the visible points x by ray casting
(dermis.geometry.raycast: Embree). There the renderer evaluates, as tsd/final.frag does,

    L_o(x) = [sum_k w_k(rgb) sum_y A_y G(v_k, |x - y|) E'(y)] albedo(x)^(1 - mix) / pi (1 - rho_s a(N.V, m) / pi)
             + specular(x)

where y runs over area-weighted surface samples (sampling.surface_cells: the surface cut into
lattice cells, A_y their area in mm^2), E'(y) is the irradiance that scatters (shading.scattered_irradiance: exact ray-cast
shadows, energy left by the specular, SH ambient occluded by the ray-cast visible fraction of the environment
irradiance (geometry/visibility.py), times albedo^mix), |x - y| is the
true 3-D distance in mm (integrate.py: KD-tree, per-Gaussian cutoff at 1e-4 of its peak, so light
through ears and nostrils is part of the same integral), w_k the profile's weights normalised
per channel (as tsd's), and the specular is KS_Skin_Specular with the same hard shadow, plus the environment's specular as the Monte Carlo integral of the same
BRDF against the HDR (shading.environment_specular_mc; the real-time techniques prefilter it)
with the same specular occlusion (shading.specular_and_exit). The procedural pore normals of the real-time
final pass are not reproduced: compare with ``pore_strength = 0`` (``dermis validate`` does).

Non-skin surfaces (glTF metallic-roughness primitives, Scene.surfaces) are hit by the same
camera rays and shadow rays (they shadow the skin and are shadowed by it) and shaded with the
glTF BRDF at the visible point (reference/metallic_roughness.py); alphaMode MASK is refused.

Output: as Renderer.render, linear float32 (H, W, 3), row 0 = top, the scene's background where
no sub-pixel ray hits the mesh (sub-pixel results averaged, like an MSAA resolve).
Deterministic for a given seed. Cost grows with the visible area / min_spacing^2.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from dermis.camera import camera_matrices
from dermis.errors import DermisError
from dermis.geometry.raycast import RayCaster
from dermis.reference.integrate import TISSUE_TAU, gather, plan_levels
from dermis.reference.metallic_roughness import SurfaceProps
from dermis.reference.sampling import SurfaceModel, coarsen, surface_cells
from dermis.reference.shading import LightRig, scattered_irradiance, specular_and_exit

MSAA4 = np.array([(-2, -6), (6, -2), (-6, 2), (2, 6)], np.float64) / 16.0
"""The standard 4x multisample positions (offsets from the pixel centre, in pixels, y down)."""
DEFAULT_MAX_SPACING_MM = 0.25
"""Upper bound of the automatic finest sample spacing (mm)."""
SPACING_PER_PIXEL = 0.35
"""Automatic finest sample spacing: this fraction of the median pixel footprint on the surface."""
IRRADIANCE_CHUNK = 200_000


@dataclass
class ReferenceResult:
    image: np.ndarray  # (H, W, 3) float32 linear radiance, background where nothing is hit
    coverage: np.ndarray  # (H, W) float32: fraction of sub-pixel rays that hit the mesh
    diffuse: np.ndarray  # (H, W, 3) float32, mean over the hitting sub-pixel rays (0 elsewhere)
    specular: np.ndarray  # (H, W, 3) float32, likewise
    positions_mm: np.ndarray | None = None  # (H, W, 3) mean visible point (mm, world axes), NaN where none
    stats: dict = field(default_factory=dict)


def subpixel_offsets(spp: int) -> np.ndarray:
    """(spp, 2) offsets from the pixel centre in pixels (x right, y down)."""
    if spp == 1:
        return np.zeros((1, 2))
    if spp == 4:
        return MSAA4.copy()
    n = int(round(math.sqrt(spp)))
    if n * n != spp:
        raise DermisError(f"spp: must be 1, 4 or a square number, got {spp}")
    g = (np.arange(n) + 0.5) / n - 0.5
    xx, yy = np.meshgrid(g, g)
    return np.stack([xx.ravel(), yy.ravel()], 1)


def camera_rays(scene, size, spp: int = 1, camera=None):
    """World-space rays (scene units) through the sub-pixel positions of every pixel.

    Returns (origins (H*W*spp, 3), unit directions, tmax along them, eye); ray p*spp + s belongs to
    pixel p = row * W + col (row 0 = top), sub-pixel s. Origins lie on the near plane.
    """
    w, h = size
    cam = camera or scene.camera
    lo, hi = scene.bounds()
    view, proj, eye, near, far = camera_matrices(cam, w / h, lo, hi)
    inv = np.linalg.inv(proj @ view)
    offs = subpixel_offsets(spp)
    cols, rows = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    px = (cols.reshape(-1, 1) + 0.5 + offs[None, :, 0]).reshape(-1)
    py = (rows.reshape(-1, 1) + 0.5 + offs[None, :, 1]).reshape(-1)
    ndc_x = px / w * 2.0 - 1.0
    ndc_y = 1.0 - py / h * 2.0

    def unproject(z):
        q = np.stack([ndc_x, ndc_y, np.full_like(ndc_x, z), np.ones_like(ndc_x)], 1) @ inv.T
        return q[:, :3] / q[:, 3:4]

    a, b = unproject(-1.0), unproject(1.0)
    d = b - a
    length = np.linalg.norm(d, axis=1)
    return a, d / length[:, None], length, eye


def _power_centroids(group, n_groups, area, position, power):
    """Where a coarse cell's light is: the centroid of its fine pieces weighted by area x power
    (sum of RGB), so the coarse sample keeps the first moment of the light it carries and a spot
    smaller than the cell stays where it is; the area centroid where the cell is dark."""
    w_area = area
    w_power = area * np.maximum(power, 0.0)
    tot_a = np.bincount(group, weights=w_area, minlength=n_groups)
    tot_p = np.bincount(group, weights=w_power, minlength=n_groups)
    lit = tot_p > 1e-12 * np.maximum(tot_a, 1e-300) * max(float(np.max(power, initial=0.0)), 1e-300)
    w = np.where(lit[group], w_power, w_area)
    tot = np.where(lit, tot_p, tot_a)
    return np.stack([np.bincount(group, weights=w * position[:, c], minlength=n_groups) for c in range(3)], 1) / \
        np.maximum(tot, 1e-300)[:, None]


class _Progress:
    def __init__(self, enabled, total):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=int(total), unit="pt", unit_scale=True, desc="reference", leave=True, dynamic_ncols=True)

    def stage(self, name):
        if self.bar is not None:
            self.bar.set_description(name)

    def __call__(self, n):
        if self.bar is not None:
            self.bar.update(int(n))

    def add_total(self, n):
        if self.bar is not None:
            self.bar.total += int(n)
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.close()


def render_reference(scene, size=(256, 256), *, spp: int = 4, min_spacing_mm: float | None = None, seed: int = 0,
                     progress: bool = True, camera=None, paths: str = "straight") -> ReferenceResult:
    """Render ``scene`` offline; see the module docstring. ``min_spacing_mm``: the finest surface
    sample spacing (default: SPACING_PER_PIXEL of the median pixel footprint, at most 0.25 mm).

    ``paths``: "straight" (default) - every pair of points within the cutoff exchanges light by
    their 3-D distance, as the model is defined; "tissue" - pairs whose straight segment leaves
    either point into the air (integrate.TISSUE_TAU) go round the concave bend between them inside
    the tissue (integrate._tissue_path: the kernel at that longer path), or exchange nothing
    where no single bend joins them, so no light crosses the air gap of a crease (closed eyelids,
    lips, nostril and ear folds) while light through thin parts (ears) still counts. The
    difference between the two bounds what creases mean for a technique.
    """
    if paths not in ("straight", "tissue"):
        raise DermisError(f"paths must be 'straight' or 'tissue', got '{paths}'")
    from dermis.renderer import check_size

    masked = [s.material.name for s in getattr(scene, "surfaces", []) if s.material.alpha_mode == "MASK"]
    if masked:
        raise DermisError(f"{scene.source}: the reference renderer does not support alphaMode MASK (material "
                          f"{', '.join(masked)}): its rays do not test alpha")
    w, h = check_size(size)
    if spp < 1:
        raise DermisError(f"spp: must be >= 1, got {spp}")
    if len(scene.lights) > LightRig.MAX_LIGHTS:
        raise DermisError(f"{scene.source}: the reference handles at most {LightRig.MAX_LIGHTS} lights, as the techniques do")
    t_start = time.perf_counter()
    timings = {}
    mm = float(scene.mm_per_unit)
    t0 = time.perf_counter()
    surface = SurfaceModel(scene)
    skin_bvh = RayCaster(surface.positions_mm, surface.indices)
    props, bvh = None, skin_bvh
    if getattr(scene, "surfaces", None):  # non-skin surfaces: their triangles after the skin's
        props = SurfaceProps(scene, len(surface.indices))
        bvh = RayCaster(np.concatenate([surface.positions_mm, props.positions_mm]),
                        np.concatenate([surface.indices, props.indices + len(surface.positions_mm)]))
    # ambient occlusion of the skin by the skin alone, as the real-time bake (geometry/visibility.py)
    rig = LightRig(scene, surface, bvh, ambient_bvh=skin_bvh)
    timings["setup_s"] = time.perf_counter() - t0

    # visible points
    t0 = time.perf_counter()
    origins, dirs, tmax, eye = camera_rays(scene, (w, h), spp, camera)
    t_hit, tri, bary = bvh.closest_hit(origins * mm, dirs, 0.0, tmax * mm)
    hit = tri >= 0
    skin_hit = hit & (tri < len(surface.indices))
    hit_idx = np.nonzero(skin_hit)[0]
    prop_idx = np.nonzero(hit & ~skin_hit)[0]
    timings["camera_rays_s"] = time.perf_counter() - t0
    n_hits = len(hit_idx)
    eye_mm = np.asarray(eye, np.float64) * mm
    profile = scene.profile.normalized()
    stats = {"size": [w, h], "spp": spp, "paths": paths, "camera_rays": int(len(tri)), "visible_points": n_hits, "seed": seed,
             "triangles": int(len(surface.indices))}

    diffuse = np.zeros((n_hits, 3))
    specular = np.zeros((n_hits, 3))
    if n_hits:
        attrs_x = surface.interpolate(tri[hit_idx], bary[hit_idx])
        xq = attrs_x["position"]
        # finest spacing from the pixel footprint: distance * (2 tan(fov/2) / H)
        cam = camera or scene.camera
        foot = t_hit[hit_idx] * 2.0 * math.tan(math.radians(cam.fov_deg) / 2.0) / h
        pixel_mm = float(np.median(foot))
        if min_spacing_mm is None:
            min_spacing_mm = min(DEFAULT_MAX_SPACING_MM, SPACING_PER_PIXEL * pixel_mm)
        if not min_spacing_mm > 0:
            raise DermisError(f"min_spacing_mm: must be > 0 mm, got {min_spacing_mm}")
        levels, sets = plan_levels(profile, min_spacing_mm)
        stats.update({"pixel_footprint_mm": pixel_mm, "min_spacing_mm": float(min_spacing_mm),
                      "gaussians": [{"variance_mm2": l.variance_mm2, "integrated_variance_mm2": l.effective_variance_mm2,
                                     "cutoff_mm": l.cutoff_mm, "sample_set": l.set_index} for l in levels]})
        # the finest cells cover every triangle within the widest cutoff of a visible point
        t0 = time.perf_counter()
        vis_tree = cKDTree(xq)
        reach = max(s.cutoff_mm for s in sets)
        dist, _ = vis_tree.query(surface.centroids, k=1, distance_upper_bound=reach + float(surface.radii.max()))
        tri_dist = np.where(np.isfinite(dist), dist - surface.radii, np.inf)  # a lower bound per triangle
        near = np.nonzero(tri_dist <= reach)[0]
        ct, cij, cb, ca = surface_cells(surface.v0, surface.v1, surface.v2, near, min_spacing_mm, seed=seed)
        timings["sampling_s"] = time.perf_counter() - t0
        n_cells = len(ct)
        bar = _Progress(progress, n_cells + n_hits * len(sets) + n_hits)
        try:
            bar.stage("irradiance")
            t0 = time.perf_counter()
            cpos = np.empty((n_cells, 3))
            cval = np.empty((n_cells, 3))
            cnrm = np.empty((n_cells, 3)) if paths == "tissue" else None
            for c0 in range(0, n_cells, IRRADIANCE_CHUNK):
                c1 = min(n_cells, c0 + IRRADIANCE_CHUNK)
                a = surface.interpolate(ct[c0:c1], cb[c0:c1])
                cpos[c0:c1] = a["position"]
                if cnrm is not None:
                    cnrm[c0:c1] = a["normal_facet"]
                cval[c0:c1] = scattered_irradiance(surface, rig, a)
                bar(c1 - c0)
            timings["irradiance_s"] = time.perf_counter() - t0
            set_stats = []
            C = np.zeros((n_hits, profile.k, 3))
            t_gather = 0.0
            pairs_total = 0
            for si, s in enumerate(sets):
                bar.stage(f"profile integral {si + 1}/{len(sets)}")
                t0 = time.perf_counter()
                use = np.nonzero(tri_dist[ct] <= s.cutoff_mm)[0]  # cells whose triangle can reach a visible point
                group, n_groups = coarsen(ct[use], cij[use], s.factor)
                area = np.bincount(group, weights=ca[use], minlength=n_groups)
                inv = 1.0 / np.maximum(area, 1e-300)
                val = np.stack([np.bincount(group, weights=ca[use] * cval[use, c], minlength=n_groups) for c in range(3)], 1) * inv[:, None]
                pos = _power_centroids(group, n_groups, ca[use], cpos[use], cval[use].sum(axis=1))
                nrm = None
                if paths == "tissue":
                    nrm = np.stack([np.bincount(group, weights=ca[use] * cnrm[use, c], minlength=n_groups) for c in range(3)], 1)
                    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
                ks = [l.index for l in s.levels]
                out, pairs = gather(xq, pos, area, val, [l.effective_variance_mm2 for l in s.levels],
                                    [l.cutoff_mm for l in s.levels], progress=bar,
                                    query_normals=attrs_x["normal_facet"],
                                    sample_normals=nrm, tissue_tau=TISSUE_TAU if paths == "tissue" else None)
                C[:, ks, :] = out
                pairs_total += pairs
                t_gather += time.perf_counter() - t0
                set_stats.append({"cell_mm": s.spacing_mm, "cutoff_mm": s.cutoff_mm, "gaussians": ks,
                                  "samples": int(n_groups), "area_mm2": float(area.sum()), "pairs": int(pairs)})
            timings["profile_integral_s"] = t_gather
            bar.stage("specular")
            t0 = time.perf_counter()
            spec, exit_factor = specular_and_exit(surface, rig, attrs_x, eye_mm)
            bar(n_hits)
            timings["specular_s"] = time.perf_counter() - t0
        finally:
            bar.close()
        scattered = np.einsum("nkc,kc->nc", C, profile.weights)
        diffuse = scattered * exit_factor
        specular = spec
        stats["sample_sets"] = set_stats
        stats["samples"] = int(n_cells)
        stats["sampled_area_mm2"] = float(ca.sum())
        stats["pairs"] = int(pairs_total)

    prop_diffuse = prop_specular = np.zeros((0, 3))
    if len(prop_idx):  # non-skin surfaces: the glTF BRDF at the point (reference/metallic_roughness.py)
        t0 = time.perf_counter()
        prop_diffuse, prop_specular = props.shade(tri[prop_idx], bary[prop_idx], eye_mm, rig, bvh, surface.env_sh, surface.env_image)
        timings["surfaces_s"] = time.perf_counter() - t0
    stats["surface_points"] = int(len(prop_idx))

    # resolve sub-pixel samples into pixels
    bg = np.asarray(scene.output.background, np.float64)
    rad = np.broadcast_to(bg, (len(tri), 3)).copy()
    rad[hit_idx] = diffuse + specular
    rad[prop_idx] = prop_diffuse + prop_specular
    image = rad.reshape(h, w, spp, 3).mean(axis=2)
    cov = hit.reshape(h, w, spp).mean(axis=2)
    dsum = np.zeros((len(tri), 3))
    ssum = np.zeros((len(tri), 3))
    dsum[hit_idx] = diffuse
    ssum[hit_idx] = specular
    dsum[prop_idx] = prop_diffuse
    ssum[prop_idx] = prop_specular
    nh = np.maximum(hit.reshape(h, w, spp).sum(axis=2), 1)[:, :, None]
    psum = np.zeros((len(tri), 3))
    if n_hits:
        psum[hit_idx] = xq
    if len(prop_idx):
        psum[prop_idx] = origins[prop_idx] * mm + dirs[prop_idx] * t_hit[prop_idx, None]
    positions = psum.reshape(h, w, spp, 3).sum(axis=2) / nh
    positions[cov == 0] = np.nan
    stats["timings_s"] = {k: round(v, 3) for k, v in timings.items()}
    stats["total_s"] = round(time.perf_counter() - t_start, 3)
    if not np.all(np.isfinite(image)):
        raise DermisError(f"{scene.source}: the reference produced NaN or infinite values (bad scene values?)")
    return ReferenceResult(image=image.astype(np.float32), coverage=cov.astype(np.float32),
                           diffuse=(dsum.reshape(h, w, spp, 3).sum(axis=2) / nh).astype(np.float32),
                           specular=(ssum.reshape(h, w, spp, 3).sum(axis=2) / nh).astype(np.float32),
                           positions_mm=positions.astype(np.float32), stats=stats)
