"""The MCML Monte Carlo against an exact transport solution, then the diffusion models against it.

Photon counts are sized for CI (the numba kernel compiles once, ~5-10 s; each run below takes
0.2-3 s on 2 cores). Tolerances come from the runs' own standard errors.
"""

from __future__ import annotations

import numpy as np
import pytest

from dermis.errors import DermisError
from dermis.profiles.dipole import dipole_reflectance
from dermis.profiles.medium import Layer, Medium
from dermis.profiles.monte_carlo import annulus_average, monte_carlo_reflectance
from dermis.profiles.photon_beam_diffusion import pbd_reflectance


def chandrasekhar_plane_albedo(albedo: float, mu0: float = 1.0) -> float:
    """Diffuse reflectance of a semi-infinite isotropic scatterer with an index-matched surface for a
    collimated beam at cos(theta) = mu0: 1 - H(mu0) sqrt(1 - albedo) (Chandrasekhar 1960,
    Radiative Transfer, ch. IV), with H from its integral equation
    1/H(mu) = sqrt(1 - albedo) + albedo/2 integral_0^1 mu' H(mu') / (mu + mu') dmu'."""
    nodes, weights = np.polynomial.legendre.leggauss(400)
    mu, w = 0.5 * (nodes + 1.0), 0.5 * weights
    h = np.ones_like(mu)
    for _ in range(10000):
        new = 1.0 / (np.sqrt(1 - albedo) + 0.5 * albedo * ((w * mu * h)[None, :] / (mu[:, None] + mu[None, :])).sum(1))
        if np.max(np.abs(new - h)) < 1e-15:
            break
        h = new
    h0 = 1.0 / (np.sqrt(1 - albedo) + 0.5 * albedo * np.sum(w * mu * h / (mu0 + mu)))
    return float(1.0 - h0 * np.sqrt(1 - albedo))


@pytest.mark.parametrize("albedo", [0.5, 0.9])
def test_monte_carlo_total_reflectance_matches_chandrasekhar(albedo):
    medium = Medium(1.0 - albedo, albedo, 0.0, 1.0)  # isotropic, index-matched: exact H-function case
    result = monte_carlo_reflectance([Layer(medium, np.inf)], 200_000, [0.0, 1.0, 10.0], seed=11)
    reference = chandrasekhar_plane_albedo(albedo)
    assert abs(result.total_reflectance - reference) < 4.0 * result.total_reflectance_standard_error
    assert result.total_reflectance_standard_error < 0.004 * reference
    # a semi-infinite medium transmits nothing; reflected + absorbed power is all that entered
    assert result.total_transmittance == 0.0
    assert result.total_reflectance + result.absorbed == pytest.approx(1.0, abs=0.01)


def test_monte_carlo_is_seeded_and_reports_the_specular_part_apart():
    layers = [Layer(Medium(0.1, 2.0, 0.5, 1.4), 0.3), Layer(Medium(0.05, 1.0, 0.0, 1.4), np.inf)]
    edges = np.geomspace(0.05, 5.0, 6)
    first = monte_carlo_reflectance(layers, 4000, edges, seed=5)
    again = monte_carlo_reflectance(layers, 4000, edges, seed=5)
    other = monte_carlo_reflectance(layers, 4000, edges, seed=6)
    np.testing.assert_array_equal(first.reflectance_per_mm2, again.reflectance_per_mm2)
    assert first.total_reflectance == again.total_reflectance != other.total_reflectance
    assert first.specular_reflectance == pytest.approx((0.4 / 2.4) ** 2)


def test_photon_beam_diffusion_agrees_with_monte_carlo_within_7_percent():
    """Habel et al. 2013's test slab (sigma_s = 1, sigma_a = 0.01 /mm, eta = 1.4, isotropic).

    Per annulus between 0.1 and 5 mm: |PBD - MC| <= 7 % of MC + 3 standard errors, and the run is
    large enough that 3 standard errors stay below 3 % (else the check would be toothless)."""
    medium = Medium(0.01, 1.0, 0.0, 1.4)
    edges = np.geomspace(0.1, 5.0, 7)
    result = monte_carlo_reflectance([Layer(medium, np.inf)], 600_000, edges, seed=2024)
    mc, se = result.reflectance_per_mm2, result.standard_error_per_mm2
    assert np.all(3 * se < 0.03 * mc)
    pbd = annulus_average(lambda r: pbd_reflectance(r, medium), edges)
    deviation = np.abs(pbd - mc)
    print("PBD / MC - 1 per annulus:", np.round(pbd / mc - 1, 4), "relative SE:", np.round(se / mc, 4))
    assert np.all(deviation <= 0.07 * mc + 3 * se)
    # the same MC tells the classic dipole apart: it is off by far more near the source
    dipole = annulus_average(lambda r: dipole_reflectance(r, medium), edges)
    assert abs(dipole[0] / mc[0] - 1) > 0.3


def test_monte_carlo_bad_input_is_refused():
    medium = Medium(0.1, 1.0)
    with pytest.raises(DermisError, match="photons"):
        monte_carlo_reflectance([Layer(medium, np.inf)], 1, [0.0, 1.0])
    with pytest.raises(DermisError, match="bin edges"):
        monte_carlo_reflectance([Layer(medium, np.inf)], 100, [1.0, 0.5])
    with pytest.raises(DermisError, match="last layer"):
        monte_carlo_reflectance([Layer(medium, np.inf), Layer(medium, 1.0)], 100, [0.0, 1.0])


def test_monte_carlo_slab_transmission_of_a_pure_absorber_is_closed_form_and_on_axis():
    """The far face's radial tally (issue 12, round 7: the transmitted light's spread). A pencil beam
    in a non-scattering slab (index 1.4 in air) runs straight down: it crosses the slab with chance
    e^(-mu_a d), the far face lets out 1 - F (normal incidence) and turns F back, so
    T = (1 - F) e / (1 - F^2 e^2), R = F (1 - F) e^2 / (1 - F^2 e^2), e = e^(-mu_a d); and all of T
    leaves on the axis (the first annulus)."""
    mu_a, d, n = 0.7, 1.3, 1.4
    edges = np.array([0.0, 0.01, 1.0, 10.0])
    photons = 100_000
    res = monte_carlo_reflectance([Layer(Medium(mu_a, 0.0, 0.0, n), d)], photons, edges, seed=4)
    f, e = ((n - 1.0) / (n + 1.0)) ** 2, np.exp(-mu_a * d)
    t_exact = (1 - f) * e / (1 - f * f * e * e)
    r_exact = f * (1 - f) * e * e / (1 - f * f * e * e)
    # each photon's score is 0 or 1: binomial standard errors
    assert abs(res.total_transmittance - t_exact) < 4.0 * np.sqrt(t_exact * (1 - t_exact) / photons)
    assert abs(res.total_reflectance - r_exact) < 4.0 * np.sqrt(r_exact * (1 - r_exact) / photons) + 1e-12
    area = np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    tallied = res.transmittance_per_mm2 * area
    assert tallied[0] == pytest.approx(res.total_transmittance, rel=1e-12)
    assert tallied[1:].sum() == 0.0


def test_monte_carlo_slab_transmission_tally_sums_to_the_total_and_spreads_with_thickness():
    """A scattering slab: the far face's annuli add up to total_transmittance (bins out to 1 m), and
    the transmitted light's mean radius grows with the thickness (it has wandered further)."""
    medium = Medium(0.05, 3.0, 0.0, 1.4)
    edges = np.concatenate([np.linspace(0.0, 10.0, 101), [1000.0]])
    area = np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    rc = 0.5 * (edges[1:] + edges[:-1])
    radii = []
    for d in (1.0, 3.0):
        res = monte_carlo_reflectance([Layer(medium, d)], 20_000, edges, seed=2)
        tallied = res.transmittance_per_mm2 * area
        assert tallied.sum() == pytest.approx(res.total_transmittance, rel=1e-9)
        radii.append(float((tallied * rc)[:-1].sum() / tallied[:-1].sum()))
    assert radii[1] > 1.5 * radii[0], radii


@pytest.mark.parametrize("mu0", [0.3, 0.7])
def test_monte_carlo_oblique_incidence_matches_chandrasekhar(mu0):
    """``incidence_cos``: a beam at cos(theta) = mu0 (index-matched, so it enters unrefracted) is
    reflected 1 - H(mu0) sqrt(1 - albedo) (Chandrasekhar's H-function, exact): more at grazing
    incidence, where the first scattering is shallower. (With skin's index 1.4 the beam refracts to
    within 46 deg of the normal and the rise is small: ear_translucency.py --boundary.)"""
    albedo = 0.9
    medium = Medium(1.0 - albedo, albedo, 0.0, 1.0)
    result = monte_carlo_reflectance([Layer(medium, np.inf)], 100_000, [0.0, 10.0], seed=7, incidence_cos=mu0)
    reference = chandrasekhar_plane_albedo(albedo, mu0)
    assert abs(result.total_reflectance - reference) < 4.0 * result.total_reflectance_standard_error
    assert reference > chandrasekhar_plane_albedo(albedo, 1.0) + 0.05  # the test can tell oblique from normal
    with pytest.raises(DermisError, match="incidence cosine"):
        monte_carlo_reflectance([Layer(medium, np.inf)], 10, [0.0, 1.0], incidence_cos=0.0)
