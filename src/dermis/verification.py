"""Independent references for verifying the techniques: flat quads with a known number of mm per
texel, the impulse response of a sum of Gaussians integrated over texel footprints (closed form),
and the r-weighted L2 error. Used by the tests and by ``dermis bench``."""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np
from scipy.special import erf

from dermis.geometry.texture_space import texture_space_uvs
from dermis.scene.builtin import grid_mesh
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial


def quad_scene(width_mm: float, height_mm: float, n: int = 8) -> Scene:
    """A quad in the x-y plane facing +z, width_mm x height_mm, UVs covering [0, 1]^2 (so a
    non-square quad is stretched in texture space); mm_per_unit = 1."""

    def fn(u, v):
        p = np.stack([(u - 0.5) * width_mm, (v - 0.5) * height_mm, np.zeros_like(u)], -1)
        return p, np.broadcast_to([0.0, 0.0, 1.0], p.shape)

    p, nn, uv, t = grid_mesh(n, n, fn)
    mesh = finish_mesh(p, nn, uv, t, "test:quad", "v-up")
    scene = Scene(mesh=mesh, material=SkinMaterial(albedo_color=(1.0, 1.0, 1.0), rho_s=0.0, pore_strength=0.0),
                  lights=[Light(direction=(0.0, 0.0, -1.0), intensity=np.pi, cast_shadows=False)],
                  camera=Camera(position=(0.0, 0.0, 3.0 * max(width_mm, height_mm)), fov_deg=25.0),
                  environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0, name="quad")
    return scene


SKIN_ALBEDO = (0.535, 0.321, 0.264)  # the Lee Perry-Smith albedo map's mean (back-ears.toml), linear


def backlit_slab_scene(thickness_mm: float, size_mm: float = 30.0, fov_deg: float = 10.0, n: int = 16,
                       albedo=(1.0, 1.0, 1.0)) -> Scene:
    """A square slab (size_mm, thickness_mm thick, mm_per_unit = 1), of constant ``albedo``, no
    specular, lit from behind by a directional light of irradiance pi travelling towards the camera
    on +z: the front face receives only light transmitted through the slab."""
    from dermis.scene.builtin import slab

    p, nn, uv, t = slab(size=size_mm, thickness=thickness_mm, n=n)
    mesh = finish_mesh(p, nn, uv, t, f"test:slab{thickness_mm}", "v-up")
    return Scene(mesh=mesh, material=SkinMaterial(albedo_color=tuple(albedo), rho_s=0.0, pore_strength=0.0),
                 lights=[Light(direction=(0.0, 0.0, 1.0), intensity=np.pi)],
                 camera=Camera(position=(0.0, 0.0, 120.0), fov_deg=fov_deg),
                 environment=Environment(color=(0.0, 0.0, 0.0)), mm_per_unit=1.0)


def binned_gaussian_1d(centers_mm, variance_mm2, texel_mm):
    """Mass of a 1-D Gaussian (variance v, centred at 0) in each texel [c - h, c + h]: the profile
    integrated over the receiving texel's footprint (closed form, erf)."""
    s = np.sqrt(2.0 * variance_mm2)
    c = np.asarray(centers_mm, np.float64)
    h = texel_mm / 2
    return 0.5 * (erf((c + h) / s) - erf((c - h) / s))


def impulse_reference(profile, shape, center, texel_u_mm, texel_v_mm):
    """sum_k w_k (G(v_k) convolved with the texel footprint) integrated over each texel, per
    channel (weights normalised per channel), on a (H, W) grid; row = v index from the top."""
    H, W = shape
    ys = (np.arange(H) - center[0]) * texel_v_mm
    xs = (np.arange(W) - center[1]) * texel_u_mm
    w = profile.normalized().weights
    out = np.zeros((H, W, 3))
    for k, v in enumerate(profile.variances_mm2):
        g = np.outer(binned_gaussian_1d(ys, v, texel_v_mm), binned_gaussian_1d(xs, v, texel_u_mm))
        out += g[:, :, None] * w[k][None, None, :]
    return out


def rweighted_error(measured, reference, mask):
    """sqrt(sum (m - r)^2 / sum r^2) over the mask: the r-weighted radial L2 error, since
    integral r (f - R)^2 dr over radius is the plane integral over area / 2 pi."""
    d = (measured - reference)[mask]
    return np.sqrt((d ** 2).sum(axis=0) / (reference[mask] ** 2).sum(axis=0))


def impulse_response(S: int, shape_mm, renderer_ctx=None, multires: bool = True, profile=None):
    """tsd's diffuse response, in texture space, to irradiance 1 in the centre texel of a flat
    quad of shape_mm (mm, spanning the whole S x S layout). Returns (scene, (S, S, 3) response,
    centre texel (row, col), blur levels used)."""
    from dermis.renderer import Renderer

    sc = quad_scene(*shape_mm)
    if profile is not None:
        sc.profile = profile
    with Renderer(sc, (32, 32), irradiance_size=S, ctx=renderer_ctx, samples=0) as r:
        r.render("tsd")
        tsd = r.technique("tsd", multires=multires)
        irr = np.zeros((S, S, 4), np.float32)
        irr[..., 3] = 1.0
        c = (S // 2, S // 2)
        irr[c[0], c[1], :3] = 1.0
        tsd.texture_space(r.last_frame, irradiance=irr)
        return sc, tsd.combined(r.last_frame), c, list(tsd.levels)


def impulse_error(renderer_ctx=None, S: int = 256, texel_mm: float = 0.1, multires: bool = True, profile=None):
    """r-weighted L2 error per channel of tsd's impulse response against the closed form, out to
    3 sigma of the widest Gaussian."""
    sc, comb, c, _ = impulse_response(S, (S * texel_mm, S * texel_mm), renderer_ctx, multires, profile)
    ref = impulse_reference(sc.profile, (S, S), c, texel_mm, texel_mm)
    yy, xx = np.mgrid[:S, :S]
    rr = np.hypot((yy - c[0]) * texel_mm, (xx - c[1]) * texel_mm)
    return rweighted_error(comb, ref, rr <= 3 * np.sqrt(sc.profile.variances_mm2[-1]))


def texel_positions(mesh, S: int):
    """World position (mesh units) of every texel centre of the mesh's texture-space layout
    (its texture_space_uvs, else its uvs) at S x S, row 0 = top, and the covered mask."""
    from dermis.geometry.rasterize import rasterize_uv

    uv = texture_space_uvs(mesh)
    tri, bary = rasterize_uv(uv, mesh.indices, S, S)
    cov = tri >= 0
    corners = np.asarray(mesh.positions, np.float64)[np.asarray(mesh.indices, np.int64)[np.maximum(tri, 0)]]
    pos = np.einsum("hwk,hwkc->hwc", bary.astype(np.float64), corners)
    return np.where(cov[..., None], pos, np.nan), cov


def impulse_error_on_layout(renderer_ctx=None, S: int = 256, size_mm: float = 25.6, texture_space_uv: str = "mesh",
                            profile=None):
    """tsd's impulse response on a flat square quad (size_mm, mm_per_unit = 1) in the layout that
    ``texture_space_uv`` selects ("mesh": the quad's own UVs; "generate": an xatlas atlas), against
    the closed form: irradiance 1 in the texel nearest the quad's centre, the reference
    sum_k w_k G(v_k) integrated over each texel's footprint in mm. A planar chart maps to the plane
    by a similarity, so each texel is a square of side h (mm) along two orthogonal directions and
    the footprint integral separates along them (binned_gaussian_1d). Returns (r-weighted L2
    error per channel out to 3 sigma of the widest Gaussian, texel size h in mm)."""
    from dermis.renderer import Renderer

    sc = quad_scene(size_mm, size_mm)
    sc.mesh.texture_space_uv = texture_space_uv
    if profile is not None:
        sc.profile = profile
    with Renderer(sc, (32, 32), irradiance_size=S, ctx=renderer_ctx, samples=0) as r:
        r.render("tsd")
        tsd = r.technique("tsd")
        pos, cov = texel_positions(sc.mesh, S)
        d2 = np.where(cov, np.nansum(pos ** 2, axis=2), np.inf)
        c = np.unravel_index(np.argmin(d2), d2.shape)
        irr = np.zeros((S, S, 4), np.float32)
        irr[..., 3] = cov
        irr[c[0], c[1], :3] = 1.0
        tsd.texture_space(r.last_frame, irradiance=irr)
        comb = tsd.combined(r.last_frame)
    # texel axes in mm: one column (u) and one row (v, downwards) from the centre texel
    eu, ev = pos[c[0], c[1] + 1] - pos[c], pos[c[0] + 1, c[1]] - pos[c]
    hu, hv = np.linalg.norm(eu), np.linalg.norm(ev)
    off = pos - pos[c]
    au, av = np.einsum("hwc,c->hw", off, eu / hu), np.einsum("hwc,c->hw", off, ev / hv)
    w = sc.profile.normalized().weights
    ref = np.zeros((S, S, 3))
    for k, v in enumerate(sc.profile.variances_mm2):
        g = binned_gaussian_1d(np.nan_to_num(au), v, hu) * binned_gaussian_1d(np.nan_to_num(av), v, hv)
        ref += g[:, :, None] * w[k][None, None, :]
    rr = np.where(cov, np.hypot(au, av), np.inf)
    return rweighted_error(comb, ref, rr <= 3 * np.sqrt(sc.profile.variances_mm2[-1])), float(hu)


def seam_deviation(scene, size: int = 128, irradiance_size: int = 256, renderer_ctx=None):
    """Largest relative step of tsd's image across the texture-space seams seen on the lit side:
    on every seam (an edge the layout cuts: one triangle per side in the texture-space topology,
    two once vertices are welded by position) facing the camera, |q(seam) / median(q around) - 1|
    with q = tsd / lambert luminance (the cosine falloff divided out; lambert has no texture-
    space seams). Returns (max deviation, number of seam pixels tested)."""
    from scipy import ndimage

    from dermis.camera import camera_matrices
    from dermis.renderer import Renderer

    with Renderer(scene, (size, size), irradiance_size=irradiance_size, ctx=renderer_ctx, samples=0) as r:
        tsd = r.render("tsd")
        lam = r.render("lambert")
    m = scene.mesh
    p = np.asarray(m.positions, np.float64)
    t = np.asarray(m.indices, np.int64)
    _, weld = np.unique(np.round(p, 6), axis=0, return_inverse=True)
    weld = weld.reshape(-1)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    key = np.sort(e, axis=1)
    ek, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    wk = np.sort(weld[e], axis=1)
    _, winv, wcnt = np.unique(wk, axis=0, return_inverse=True, return_counts=True)
    seam = (cnt[inv.reshape(-1)] == 1) & (wcnt[winv.reshape(-1)] == 2)
    se = e[seam]
    fr = np.linspace(0.1, 0.9, 9)
    pts = (p[se[:, 0], None] * (1 - fr[None, :, None]) + p[se[:, 1], None] * fr[None, :, None]).reshape(-1, 3)
    nrm = np.asarray(m.normals, np.float64)
    nn = (nrm[se[:, 0], None] * (1 - fr[None, :, None]) + nrm[se[:, 1], None] * fr[None, :, None]).reshape(-1, 3)
    cam = scene.camera
    view, proj, *_ = camera_matrices(cam, 1.0, *m.bounds)
    to_eye = np.asarray(cam.position, np.float64) - pts
    facing = np.einsum("ij,ij->i", nn, to_eye / np.linalg.norm(to_eye, axis=1, keepdims=True)) > 0.5
    clip = np.c_[pts[facing], np.ones(facing.sum())] @ (np.asarray(proj) @ np.asarray(view)).T
    ndc = clip[:, :2] / clip[:, 3:4]
    col = np.floor((ndc[:, 0] * 0.5 + 0.5) * size).astype(int)
    row = np.floor((0.5 - ndc[:, 1] * 0.5) * size).astype(int)
    lum_w = np.array([0.2126, 0.7152, 0.0722])
    lt, ll = tsd @ lum_w, lam @ lum_w
    lit = ll > 0.5 * ll.max()
    q = np.where(lit, lt / np.maximum(ll, 1e-12), np.nan)
    with warnings.catch_warnings():  # windows outside the lit region are all NaN: skipped below
        warnings.simplefilter("ignore", RuntimeWarning)
        around = ndimage.generic_filter(q, np.nanmedian, size=9, mode="nearest")
    ok = (row >= 4) & (row < size - 4) & (col >= 4) & (col < size - 4)
    row, col = row[ok], col[ok]
    keep = lit[row, col] & ndimage.binary_erosion(lit, iterations=4)[row, col]
    row, col = row[keep], col[keep]
    if len(row) == 0:
        return 0.0, 0
    dev = np.abs(q[row, col] / around[row, col] - 1.0)
    return float(np.nanmax(dev)), int(len(np.unique(row * size + col)))


# ---------------------------------------------------------------- ssss on the plane of issue 13
# A flat plane seen from straight above, 10 deg field of view, 0.05 mm per pixel (256 x 256), a
# 2 x 2 pixel white dot of irradiance, mix 1 (benchmarks/ssss_impulse.py, tests/test_ssss_kernel.py):
# the azimuthal average of ssss's scattered light in 1-pixel rings against sum_k w_k G(v_k)
# convolved with the dot and integrated over pixels, out to where the profile falls below 1e-3 of
# its peak.

SSSS_PLANE_SIZE_PX = 256
SSSS_PLANE_MM_PER_PX = 0.05
SSSS_PLANE_FOV_DEG = 10.0


def ssss_plane_scene(profile=None):
    """The plane, its camera and (optionally) a profile; mm_per_unit = 1."""
    sc = quad_scene(60.0, 60.0)
    distance = 0.5 * SSSS_PLANE_SIZE_PX * SSSS_PLANE_MM_PER_PX / math.tan(math.radians(SSSS_PLANE_FOV_DEG / 2.0))
    sc.camera = Camera(position=(0.0, 0.0, distance), target=(0.0, 0.0, 0.0), fov_deg=SSSS_PLANE_FOV_DEG)
    if profile is not None:
        sc.profile = profile
    return sc


def dot_reference(profile, shape, centre, px_mm):
    """The 2 x 2 dot's response: four shifted pixel impulses of irradiance 1."""
    out = 0.0
    for dy in (0, -1):
        for dx in (0, -1):
            out = out + impulse_reference(profile, shape, (centre[0] + dy, centre[1] + dx), px_mm, px_mm)
    return out


def radial_average(image, centre_mm, px_mm, edges_mm):
    h, w = image.shape[:2]
    yy, xx = np.mgrid[:h, :w]
    r = np.hypot((yy + 0.5) * px_mm - centre_mm[0], (xx + 0.5) * px_mm - centre_mm[1])
    index = np.digitize(r.ravel(), edges_mm) - 1
    flat = image.reshape(-1, 3)
    out = np.zeros((edges_mm.size - 1, 3))
    for b in range(edges_mm.size - 1):
        members = index == b
        out[b] = flat[members].mean(axis=0) if members.any() else np.nan
    return out


def profile_reach_mm(profile, fraction=1e-3):
    """Per channel, the radius beyond which sum_k w_k G(v_k, r) < fraction x its peak."""
    r = np.linspace(0.0, 40.0, 8001)
    values = profile.normalized().evaluate(r)
    reach = []
    for c in range(3):
        above = np.nonzero(values[:, c] >= fraction * values[0, c])[0]
        reach.append(r[above[-1]])
    return np.array(reach)


def ssss_plane_impulse(gl_ctx=None, profile=None, placements: int = 1):
    """ssss's response to the dot: {"error": r-weighted L2 of the ring averages per channel, "ripple":
    largest |ring ratio - 1| beyond 0.2 mm, "cut_mm": outermost lit ring, "reach_mm": where the
    profile falls below 1e-3 of its peak, "energy": scattered light / dot light}. ``placements`` > 1:
    the response averaged over that many placements of the dot (shifted by up to 7 px, shifted back
    before averaging): where ssss's outer taps are jittered per pixel this measures the kernel's
    EXPECTATION (each placement meets other pixels' draws) rather than one draw's noise."""
    from dermis.renderer import Renderer

    sc = ssss_plane_scene(profile)
    S = SSSS_PLANE_SIZE_PX
    c = (S // 2, S // 2)
    shifts = [(0, 0)] + [tuple(int(v) for v in np.random.default_rng(i).integers(-7, 8, 2)) for i in range(1, placements)]
    out = np.zeros((S, S, 3), np.float64)
    with Renderer(sc, (S, S), ctx=gl_ctx, samples=0) as renderer:
        renderer.render("ssss")
        ssss = renderer.technique("ssss")
        for dy, dx in shifts:
            irradiance = np.zeros((S, S, 3), np.float32)
            irradiance[c[0] + dy - 1:c[0] + dy + 1, c[1] + dx - 1:c[1] + dx + 1] = 1.0
            ssss.screen_space(renderer.last_frame, irradiance=irradiance)
            out += np.roll(ssss.scattered(), (-dy, -dx), axis=(0, 1)) / len(shifts)
    reference = dot_reference(sc.profile, (S, S), c, SSSS_PLANE_MM_PER_PX)
    reach = profile_reach_mm(sc.profile)
    edges = np.arange(0.0, reach.max() + SSSS_PLANE_MM_PER_PX, SSSS_PLANE_MM_PER_PX)
    # the dot's centre: the corner between its 4 pixels
    centre_mm = (c[0] * SSSS_PLANE_MM_PER_PX, c[1] * SSSS_PLANE_MM_PER_PX)
    ring_out = radial_average(out, centre_mm, SSSS_PLANE_MM_PER_PX, edges)
    ring_ref = radial_average(reference, centre_mm, SSSS_PLANE_MM_PER_PX, edges)
    mid = 0.5 * (edges[1:] + edges[:-1])
    errors, ripple, cut = [], [], []
    for ch in range(3):
        keep = (mid <= reach[ch]) & np.isfinite(ring_ref[:, ch])
        d = (ring_out[keep, ch] - ring_ref[keep, ch])
        errors.append(math.sqrt(np.sum(mid[keep] * d * d) / np.sum(mid[keep] * ring_ref[keep, ch] ** 2)))
        ratio = ring_out[keep, ch] / ring_ref[keep, ch]
        ripple.append(float(np.max(np.abs(ratio[mid[keep] > 0.2] - 1.0))))
        nonzero = np.nonzero(ring_out[:, ch] > 1e-12)[0]
        cut.append(float(mid[nonzero[-1]]) if nonzero.size else 0.0)
    return {"error": np.array(errors), "ripple": np.array(ripple), "cut_mm": np.array(cut), "reach_mm": reach,
            "energy": out.sum(axis=(0, 1)) / 4.0}


def _random_walk(alpha: float, mean_free_path_mm: float, thickness_mm: float, photons: int, seed: int,
                 index: float = 1.4, bin_edges_mm=(0.0, 1e3)):
    """MCML of the isotropic homogeneous random walk (refractive ``index`` inside, air outside)
    back-lit through ``thickness_mm`` (np.inf: semi-infinite)."""
    from dermis.profiles.medium import Layer, Medium
    from dermis.profiles.monte_carlo import monte_carlo_reflectance

    st = 1.0 / mean_free_path_mm
    m = Medium(np.array([st * (1.0 - alpha)]), np.array([st * alpha]), 0.0, index)
    return monte_carlo_reflectance([Layer(m, thickness_mm)], photons, np.asarray(bin_edges_mm, np.float64), seed=seed)


@functools.lru_cache(maxsize=64)
def random_walk_albedo(total_reflectance: float, mean_free_path_mm: float, photons: int = 20_000,
                       steps: int = 22, seed: int = 1, index: float = 1.4) -> float:
    """The single-scattering albedo whose semi-infinite random walk reflects ``total_reflectance``:
    bisection with common random numbers (the same seed every step), so it is deterministic and is
    solved once per (reflectance, mean free path, photons, steps, seed, index), not once per thickness.
    ``index``: the medium's refractive index against air (1.4: skin; 1.0: an index-matched boundary,
    a walk that ends at its first surface hit, as Cycles' random walk does)."""
    lo, hi = 0.0, 1.0 - 1e-7
    for _ in range(steps):
        a = 0.5 * (lo + hi)
        if _random_walk(a, mean_free_path_mm, np.inf, photons, seed, index).total_reflectance < total_reflectance:
            lo = a
        else:
            hi = a
    return 0.5 * (lo + hi)


def random_walk_slab(total_reflectance: float, mean_free_path_mm: float, thickness_mm: float,
                     photons: int = 100_000, bisection_photons: int = 20_000, steps: int = 22, seed: int = 1,
                     index: float = 1.4, bin_edges_mm=(0.0, 1e3)):
    """Light through a back-lit slab of the homogeneous random walk (isotropic, ``index`` inside:
    1.4 for skin, 1.0 for an index-matched walk as Cycles'; air outside) that reflects
    ``total_reflectance`` when semi-infinite: MCML (dermis.profiles.monte_carlo) at ``thickness_mm``,
    the single-scattering albedo from random_walk_albedo (bisected once per medium, cached). Returns
    (single-scattering albedo, MonteCarloResult); its total_transmittance is per unit power entering
    the far face (``bin_edges_mm``: the radial bins of both faces' tallies). The theory the
    techniques' transmittance through thin parts is held against (issue 12)."""
    alpha = random_walk_albedo(float(total_reflectance), float(mean_free_path_mm), int(bisection_photons),
                               int(steps), int(seed), float(index))
    return alpha, _random_walk(alpha, mean_free_path_mm, thickness_mm, photons, seed, index, bin_edges_mm)
