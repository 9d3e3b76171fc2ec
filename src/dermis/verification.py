"""Independent references for verifying the techniques: flat quads with a known number of mm per
texel, the impulse response of a sum of Gaussians integrated over texel footprints (closed form),
and the r-weighted L2 error. Used by the tests and by ``dermis bench``."""

from __future__ import annotations

import numpy as np
from scipy.special import erf

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


def backlit_slab_scene(thickness_mm: float, size_mm: float = 30.0, fov_deg: float = 10.0, n: int = 16) -> Scene:
    """A square slab (size_mm, thickness_mm thick, mm_per_unit = 1), white, no specular, lit from
    behind by a directional light of irradiance pi travelling towards the camera on +z: the front
    face receives only light transmitted through the slab."""
    from dermis.scene.builtin import slab

    p, nn, uv, t = slab(size=size_mm, thickness=thickness_mm, n=n)
    mesh = finish_mesh(p, nn, uv, t, f"test:slab{thickness_mm}", "v-up")
    return Scene(mesh=mesh, material=SkinMaterial(albedo_color=(1.0, 1.0, 1.0), rho_s=0.0, pore_strength=0.0),
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
