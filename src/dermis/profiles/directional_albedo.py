"""Directional albedo of a random-walk half-space: how much light a semi-infinite medium returns
when it enters along one direction, and the view-angle dependence that follows (issue 12).

A photon refracted into a half-space at a shallow angle scatters near the surface and escapes
before it is absorbed; one entering head-on goes deeper and is absorbed more. The directional
albedo R(mu) (the directional-hemispherical reflectance for light entering at mu = cos theta in
air) therefore falls toward normal incidence, and the more the lower the single-scattering albedo
alpha is (Chandrasekhar 1960, "Radiative Transfer", ch. IV: for isotropic scattering and an
index-matched boundary R(mu) = 1 - H(mu) sqrt(1 - alpha), H the H-function). A diffusion profile
(dermis's techniques) returns the same light at every angle: a Lambertian exit.

Cycles' random walk (dermis.blender.sss) is sampled from the camera: the camera ray refracts into
the medium (IOR 1.4), walks (isotropic phase: anisotropy 0) and, where it leaves the surface, the
light is gathered with a Lambertian closure. By reciprocity its pixel is (E / pi) R(mu_view): the
view side carries R(mu), the light side none (benchmarks/lip_exit_angle.py measures both). The
walk here is that one: refraction at entry by Snell's law, no Fresnel loss at entry (the
specular layer is the BSDF's, not the walk's), and either no internal reflection at exit
(``exit_fresnel=False``, Cycles' walk leaves where it meets the surface) or MCML's Fresnel
reflection of the unpolarised light at the exit (``exit_fresnel=True``).

Lengths are in mean free paths (the medium is scale invariant: R(mu) does not depend on the
radius for a half-space).
"""

from __future__ import annotations

import math

import numpy as np

from dermis.errors import DermisError

HEMISPHERE_NODES = 8
"""Gauss-Legendre nodes in mu for the hemispherical average 2 int_0^1 R(mu) mu dmu."""


def _fresnel_unpolarised(n1: float, n2: float, cos_i: np.ndarray) -> np.ndarray:
    """Unpolarised Fresnel reflectance from index n1 into n2 at incidence cosine cos_i (1 beyond
    the critical angle)."""
    cos_i = np.clip(np.abs(cos_i), 0.0, 1.0)
    sin_t2 = (n1 / n2) ** 2 * (1.0 - cos_i * cos_i)
    tir = sin_t2 >= 1.0
    cos_t = np.sqrt(np.maximum(1.0 - sin_t2, 0.0))
    rs = (n1 * cos_i - n2 * cos_t) / np.maximum(n1 * cos_i + n2 * cos_t, 1e-300)
    rp = (n1 * cos_t - n2 * cos_i) / np.maximum(n1 * cos_t + n2 * cos_i, 1e-300)
    return np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))


def walk_directional_albedo(alpha: float, mu: float, *, n: float = 1.4, exit_fresnel: bool = False,
                            photons: int = 50_000, seed: int = 0) -> tuple[float, float]:
    """(R, standard error): the fraction of light entering a half-space of single-scattering
    albedo ``alpha`` (isotropic phase, index ``n`` inside, 1 outside) from the direction whose
    cosine to the normal in air is ``mu`` that leaves through the top face again. All photons
    in parallel (numpy); the weight is multiplied by alpha at each scattering (implicit capture)
    and Russian roulette ends photons below 1e-3 of their weight (unbiased)."""
    if not 0.0 <= alpha < 1.0:
        raise DermisError(f"single-scattering albedo must lie in [0, 1), got {alpha}")
    if not 0.0 < mu <= 1.0:
        raise DermisError(f"the entry direction's cosine must lie in (0, 1], got {mu}")
    if n < 1.0:
        raise DermisError(f"the medium's index must be >= 1, got {n}")
    rng = np.random.default_rng(seed)
    cos_in = math.sqrt(1.0 - (1.0 - mu * mu) / (n * n))  # Snell: refracted toward the normal
    N = int(photons)
    z = np.zeros(N)  # depth below the surface, in mean free paths
    uz = np.full(N, cos_in)  # direction's z component (+ = into the medium)
    w = np.ones(N)
    out = np.zeros(N)  # weight that escaped, per photon
    live = np.arange(N)
    while live.size:
        s = -np.log(1.0 - rng.random(live.size))
        zn = z[live] + s * uz[live]
        up = zn < 0.0  # reaches the surface on this flight
        if exit_fresnel and up.any():
            # MCML: reflected back with the Fresnel probability, the rest of the flight continues mirrored
            j = np.nonzero(up)[0]
            refl = rng.random(j.size) < _fresnel_unpolarised(n, 1.0, uz[live[j]])
            jr = j[refl]
            zn[jr] = -zn[jr]
            uz[live[jr]] = -uz[live[jr]]
            up[jr] = False
        esc = live[up]
        out[esc] += w[esc]
        stay = live[~up]
        z[stay] = zn[~up]
        w[stay] *= alpha
        uz[stay] = 2.0 * rng.random(stay.size) - 1.0  # isotropic: cos uniform in [-1, 1]
        low = w[stay] < 1e-3
        if low.any():
            k = stay[low]
            survive = rng.random(k.size) < 0.1
            w[k] = np.where(survive, w[k] * 10.0, 0.0)
        live = stay[w[stay] > 0.0]
    return float(out.mean()), float(out.std(ddof=1) / math.sqrt(N))


def hemispherical_albedo(alpha: float, *, n: float = 1.4, exit_fresnel: bool = False, photons: int = 20_000,
                         seed: int = 0) -> float:
    """2 int_0^1 R(mu) mu dmu (Gauss-Legendre): the total reflectance under light that is uniform
    over the hemisphere, and equally of a Lambertian-gathered walk under a sun (the quantity
    Cycles' albedo inversion matches to the base colour; dermis.blender.sss's table)."""
    x, wts = np.polynomial.legendre.leggauss(HEMISPHERE_NODES)
    mus, wts = 0.5 * (x + 1.0), 0.5 * wts
    return float(sum(2.0 * wi * m * walk_directional_albedo(alpha, float(m), n=n, exit_fresnel=exit_fresnel,
                                                             photons=photons, seed=seed + i)[0]
                     for i, (m, wi) in enumerate(zip(mus, wts))))


def albedo_for_reflectance(total_reflectance: float, *, n: float = 1.4, exit_fresnel: bool = False,
                           photons: int = 20_000, steps: int = 18, seed: int = 0) -> float:
    """The single-scattering albedo whose hemispherical albedo is ``total_reflectance``: bisection
    with common random numbers (the same seeds every step, so the estimate is monotone in alpha)."""
    if not 0.0 < total_reflectance < 1.0:
        raise DermisError(f"total reflectance must lie in (0, 1), got {total_reflectance}")
    lo, hi = 0.0, 1.0 - 1e-6
    for _ in range(steps):
        a = 0.5 * (lo + hi)
        if hemispherical_albedo(a, n=n, exit_fresnel=exit_fresnel, photons=photons, seed=seed) < total_reflectance:
            lo = a
        else:
            hi = a
    return 0.5 * (lo + hi)


def exit_factor(total_reflectance: float, mus, *, n: float = 1.4, exit_fresnel: bool = False,
                photons: int = 50_000, bisection_photons: int = 20_000, seed: int = 0) -> np.ndarray:
    """k(mu) = R(mu) / R_hemispherical for the half-space whose hemispherical albedo is
    ``total_reflectance``: the factor by which a view-side random walk (Cycles') differs from a
    Lambertian exit of the same total reflectance at view cosine mu (1 on average over the
    hemisphere: 2 int k mu dmu = 1)."""
    alpha = albedo_for_reflectance(total_reflectance, n=n, exit_fresnel=exit_fresnel,
                                   photons=bisection_photons, seed=seed)
    return np.array([walk_directional_albedo(alpha, float(m), n=n, exit_fresnel=exit_fresnel, photons=photons,
                                             seed=seed + 101 + i)[0] for i, m in enumerate(mus)]) / total_reflectance


# ------------------------------------------------------------------ the exit factor's table (tsd)

TABLE = __import__("pathlib").Path(__file__).resolve().parents[1] / "data" / "directional_albedo.json"
TABLE_ALPHAS = (0.2, 0.4, 0.6, 0.7, 0.8, 0.87, 0.92, 0.95, 0.97, 0.98, 0.99, 0.995, 0.998)
"""Single-scattering albedos of the table's rows: hemispherical albedo 0.015 to about 0.8."""
TABLE_MUS = (1.0, 0.9, 0.75, 0.6, 0.45, 0.3, 0.15, 0.05)


def linear_coefficient(mus, k) -> float:
    """Least-squares c of k(mu) = 1 + c (2/3 - mu): the one-parameter form that keeps the
    hemispherical normalisation exactly (int_0^1 2 mu (2/3 - mu) dmu = 0), so a renderer can
    apply it at entry (mu = N.L) and exit (mu = N.V) without changing the total reflectance."""
    b = 2.0 / 3.0 - np.asarray(mus, np.float64)
    return float(((np.asarray(k, np.float64) - 1.0) * b).sum() / (b * b).sum())


def compute_table(photons: int = 40_000, seed: int = 11, n: float = 1.4) -> dict:
    """Rows (alpha, hemispherical albedo A, k at TABLE_MUS, c) of the physical interface: index
    ``n`` with refraction at entry and Fresnel reflection at exit (MCML's boundary)."""
    x, w = np.polynomial.legendre.leggauss(HEMISPHERE_NODES)
    nodes, wts = 0.5 * (x + 1.0), 0.5 * w
    rows = []
    for i, a in enumerate(TABLE_ALPHAS):
        # common random numbers within a row (one seed for every angle): the angular shape k is
        # then far less noisy than each R; 4x the photons where walks are short (cheap)
        ph = photons * (4 if a <= 0.92 else 1)

        def R(m):
            return walk_directional_albedo(a, float(m), n=n, exit_fresnel=True, photons=ph, seed=seed + i)[0]

        A = float((2.0 * wts * nodes * np.array([R(m) for m in nodes])).sum())
        r = np.array([R(m) for m in TABLE_MUS])
        k = r / A
        rows.append({"alpha": a, "A": round(A, 5), "k": [round(float(v), 4) for v in k],
                     "c": round(linear_coefficient(TABLE_MUS, k), 4)})
    return {"what": "directional albedo R(mu)/A of an isotropic random-walk half-space (index 1.4, refraction at "
                    "entry, Fresnel at exit) and the least-squares c of k = 1 + c (2/3 - mu); "
                    "python -m dermis.profiles.directional_albedo --table",
            "n": n, "photons": photons, "seed": seed, "mus": list(TABLE_MUS), "rows": rows}


def coefficient(total_reflectance) -> np.ndarray:
    """c(A) of the shipped table, linear in A between its rows, c(0) = the lowest row's and
    c(1) = 0 (a medium that absorbs nothing returns all light at every angle): the numpy twin of
    common/directional_albedo.glsl's directional_c."""
    import json

    rows = json.loads(TABLE.read_text())["rows"]
    a = [0.0] + [r["A"] for r in rows] + [1.0]
    c = [rows[0]["c"]] + [r["c"] for r in rows] + [0.0]
    return np.interp(np.clip(np.asarray(total_reflectance, np.float64), 0.0, 1.0), a, c)


def factor(total_reflectance, mu) -> np.ndarray:
    """k(mu) = 1 + c(A) (2/3 - mu), mu clamped to [0, 1] (common/directional_albedo.glsl)."""
    return 1.0 + coefficient(total_reflectance) * (2.0 / 3.0 - np.clip(mu, 0.0, 1.0))


def main(argv=None):
    import argparse
    import json

    ap = argparse.ArgumentParser(description="Tabulate the directional albedo of the skin's half-space.")
    ap.add_argument("--table", action="store_true")
    ap.add_argument("--photons", type=int, default=40_000)
    ap.add_argument("--out", default=str(TABLE))
    a = ap.parse_args(argv)
    if not a.table:
        ap.print_help()
        return
    d = compute_table(a.photons)
    with open(a.out, "w") as f:
        json.dump(d, f, indent=1)
    for r in d["rows"]:
        print(f"alpha {r['alpha']:.3f}  A {r['A']:.4f}  c {r['c']:.4f}  k {r['k']}")


if __name__ == "__main__":
    main()
