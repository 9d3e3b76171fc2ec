"""ssss's radial impulse response on the plane of issue 13 against the analytic sum of Gaussians.

    PYTHONPATH=src python benchmarks/ssss_impulse.py [deon|fair|...] [PLACEMENTS]

A flat plane seen from straight above, 10 deg field of view, 0.05 mm per pixel (256 x 256), a
2 x 2 pixel white dot of irradiance, mix 1: the azimuthal average of the scattered light in
1-pixel rings, against sum_k w_k G(v_k) convolved with the dot and integrated over pixels, out to
the radius where the profile falls below 1e-3 of its peak. Prints the r-weighted L2 error per
channel, the largest ripple (ring ratio - 1) and the radius where the response stops.
PLACEMENTS > 1: averaged over that many placements of the dot (the jittered kernel's expectation,
dermis.verification.ssss_plane_impulse).
"""

import sys

from dermis.verification import ssss_plane_impulse  # noqa: E402


if __name__ == "__main__":
    from dermis.profiles import deon_skin

    name = sys.argv[1] if len(sys.argv) > 1 else "deon"
    profile = deon_skin() if name == "deon" else None
    if name != "deon":
        from dermis.profiles.scene_skin import resolve_skin_profile

        profile = resolve_skin_profile({"profile": name}, ".", "benchmark")
    result = ssss_plane_impulse(profile=profile, placements=int(sys.argv[2]) if len(sys.argv) > 2 else 1)
    for key, value in result.items():
        print(f"{key:8s} " + " ".join(f"{v:.4f}" for v in value))
