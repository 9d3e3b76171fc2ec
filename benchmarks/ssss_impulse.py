"""ssss's radial impulse response on the plane of issue 13 against the analytic sum of Gaussians.

    PYTHONPATH=src python benchmarks/ssss_impulse.py [deon|fair|...]

A flat plane seen from straight above, 10 deg field of view, 0.05 mm per pixel (256 x 256), a
2 x 2 pixel white dot of irradiance, mix 1: the azimuthal average of the scattered light in
1-pixel rings, against sum_k w_k G(v_k) convolved with the dot and integrated over pixels, out to
the radius where the profile falls below 1e-3 of its peak. Prints the r-weighted L2 error per
channel, the largest ripple (ring ratio - 1) and the radius where the response stops.
"""

import math
import sys

import numpy as np

from dermis.verification import impulse_reference, quad_scene

SIZE_PX = 256
MM_PER_PX = 0.05
FOV_DEG = 10.0


def plane_scene(profile=None):
    from dermis.scene.model import Camera

    sc = quad_scene(60.0, 60.0)
    distance = 0.5 * SIZE_PX * MM_PER_PX / math.tan(math.radians(FOV_DEG / 2.0))
    sc.camera = Camera(position=(0.0, 0.0, distance), target=(0.0, 0.0, 0.0), fov_deg=FOV_DEG)
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


def measure(gl_ctx=None, profile=None):
    from dermis.renderer import Renderer

    sc = plane_scene(profile)
    S = SIZE_PX
    with Renderer(sc, (S, S), ctx=gl_ctx, samples=0) as renderer:
        renderer.render("ssss")
        ssss = renderer.technique("ssss")
        irradiance = np.zeros((S, S, 3), np.float32)
        c = (S // 2, S // 2)
        irradiance[c[0] - 1:c[0] + 1, c[1] - 1:c[1] + 1] = 1.0
        ssss.screen_space(renderer.last_frame, irradiance=irradiance)
        out = ssss.scattered()
    reference = dot_reference(sc.profile, (S, S), c, MM_PER_PX)
    reach = profile_reach_mm(sc.profile)
    edges = np.arange(0.0, reach.max() + MM_PER_PX, MM_PER_PX)
    centre_mm = (c[0] * MM_PER_PX, c[1] * MM_PER_PX)  # the dot's centre: the corner between its 4 pixels
    ring_out = radial_average(out, centre_mm, MM_PER_PX, edges)
    ring_ref = radial_average(reference, centre_mm, MM_PER_PX, edges)
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


if __name__ == "__main__":
    from dermis.profiles import deon_skin

    name = sys.argv[1] if len(sys.argv) > 1 else "deon"
    profile = deon_skin() if name == "deon" else None
    if name != "deon":
        from dermis.profiles.scene_skin import resolve_skin_profile

        profile = resolve_skin_profile({"profile": name}, ".", "benchmark")
    result = measure(profile=profile)
    for key, value in result.items():
        print(f"{key:8s} " + " ".join(f"{v:.4f}" for v in value))
