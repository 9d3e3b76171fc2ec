"""Diffusion models against closed forms and numerical quadrature (no Monte Carlo here)."""

from __future__ import annotations

import numpy as np
from scipy.integrate import trapezoid
import pytest
from scipy import integrate

from dermis.errors import DermisError
from dermis.profiles.burley import burley_mean_radius_mm, burley_reflectance, burley_scaling_factor
from dermis.profiles.dipole import dipole_reflectance, dipole_reflectance_hankel, dipole_total_reflectance
from dermis.profiles.fresnel import boundary_coefficient_a, diffuse_fresnel_reflectance, fresnel_moment
from dermis.profiles.hankel import LogRadialGrid
from dermis.profiles.medium import Layer, Medium
from dermis.profiles.multipole import multipole_profiles
from dermis.profiles.photon_beam_diffusion import pbd_reflectance, pbd_slab_profiles

MEDIA = [Medium(0.01, 1.0, 0.0, 1.4), Medium(0.5, 3.0, 0.0, 1.4), Medium(0.05, 15.0, 0.8, 1.3),
         Medium(2.0, 5.0, 0.0, 1.0)]


def test_boundary_constants_match_the_reference_doc():
    # skin-rendering.md section 2: at eta = 1.4, F_dr = 0.5295 and A = 3.251
    assert diffuse_fresnel_reflectance(1.4) == pytest.approx(0.5295, abs=1e-4)
    assert boundary_coefficient_a(1.4) == pytest.approx(3.251, abs=5e-4)
    assert boundary_coefficient_a(1.0) == 1.0


@pytest.mark.parametrize("eta", [1.2, 1.33, 1.4, 1.5])
def test_fresnel_moment_quadrature_agrees_with_the_egan_hilgeman_fit(eta):
    # 2 F_1 is the internal diffuse reflectance; the rational fit is good to ~1 %
    assert 2 * fresnel_moment(eta, 1) == pytest.approx(diffuse_fresnel_reflectance(eta), rel=0.012)


@pytest.mark.parametrize("medium", MEDIA, ids=lambda m: f"sa{m.sigma_a_per_mm[0]}-ss{m.sigma_s_per_mm[0]}")
def test_dipole_total_reflectance_equals_its_closed_form(medium):
    numeric, _ = integrate.quad(lambda r: 2 * np.pi * r * float(dipole_reflectance(r, medium)), 0, np.inf,
                                limit=400, epsabs=1e-12, epsrel=1e-10)
    assert numeric == pytest.approx(float(dipole_total_reflectance(medium)), rel=1e-7)


def test_dipole_handles_wavelength_arrays_like_scalars():
    spectral = Medium([0.01, 0.5], [1.0, 3.0], 0.0, 1.4)
    radius = np.array([0.05, 0.5, 5.0])
    both = dipole_reflectance(radius, spectral)
    assert both.shape == (3, 2)
    np.testing.assert_allclose(both[:, 1], dipole_reflectance(radius, MEDIA[1]), rtol=1e-12)


def test_fftlog_hankel_transform_of_the_dipole_matches_its_closed_form():
    grid = LogRadialGrid(1e-6, 1e3, 1024)
    medium = Medium([0.01, 0.5, 2.0], [1.0, 3.0, 5.0], 0.0, 1.4)
    numeric = grid.forward(dipole_reflectance(grid.radius_mm, medium))
    exact = dipole_reflectance_hankel(grid.wavenumber_per_mm, medium)
    k = grid.wavenumber_per_mm
    band = (k > 0.1) & (k < 1e3)  # wavelengths 6 mm .. 6 um; below, F(k) = R_d to < 1e-3
    assert np.max(np.abs(numeric - exact)[band]) < 1e-4
    np.testing.assert_allclose(exact[0], dipole_total_reflectance(medium), rtol=1e-4)  # k_min ~ 1e-3 /mm
    # and back: the inverse of the closed-form transform is the dipole again
    back = grid.inverse(exact)
    r = grid.radius_mm
    sel = (r > 1e-3) & (r < 3.0)
    reference = dipole_reflectance(r, medium)
    assert np.max(np.abs(back - reference)[sel] / reference[sel].max(axis=0)) < 1e-5


@pytest.mark.parametrize("medium", MEDIA[:3], ids=["doc-slab", "absorbing", "skin-like"])
def test_multipole_of_a_thick_slab_converges_to_the_dipole(medium):
    radius = np.geomspace(1e-3, 20.0, 60)
    reflectance, transmittance = multipole_profiles(radius, medium, 2000.0)
    np.testing.assert_allclose(reflectance, dipole_reflectance(radius, medium), rtol=1e-6)
    assert np.all(np.abs(transmittance) < 1e-12)


def test_multipole_of_a_thin_slab_differs_from_the_dipole_and_transmits():
    medium = MEDIA[2]
    radius = np.geomspace(1e-2, 10.0, 40)
    reflectance, transmittance = multipole_profiles(radius, medium, 0.5)
    assert np.max(np.abs(reflectance / dipole_reflectance(radius, medium) - 1)) > 0.2
    assert trapezoid(2 * np.pi * radius * transmittance, radius) > 0.3
    # the image series is converged: twice the pole pairs change nothing
    again, _ = multipole_profiles(radius, medium, 0.5, pair_count=80)
    np.testing.assert_allclose(reflectance, again, rtol=1e-6, atol=1e-8 * reflectance.max())


def test_pbd_of_a_thick_slab_equals_the_semi_infinite_pbd():
    medium = MEDIA[1]
    radius = np.geomspace(1e-2, 10.0, 30)
    thick = pbd_slab_profiles(radius, medium, 500.0, beam_samples=100)
    semi_infinite = pbd_reflectance(radius, medium)
    np.testing.assert_allclose(thick.reflectance[:, 0], semi_infinite, rtol=1e-6)
    assert thick.ballistic[0] < 1e-100


def test_pbd_beam_quadrature_is_converged_at_the_sample_counts_used():
    medium = Medium(0.2, 4.0, 0.0, 1.4)
    radius = np.geomspace(0.02, 10.0, 25)
    fine = pbd_slab_profiles(radius, medium, 0.25, 1.4, 1.0, beam_samples=400)
    coarse = pbd_slab_profiles(radius, medium, 0.25, 1.4, 1.0, beam_samples=32)
    for a, b in ((coarse.reflectance, fine.reflectance), (coarse.transmittance, fine.transmittance)):
        assert np.max(np.abs(a / b - 1)) < 0.01


def test_burley_profile_integrates_to_its_albedo_and_has_its_mean_radius():
    for albedo, length in ((0.2, 0.5), (0.6, 1.3), (0.95, 3.0)):
        zeroth, _ = integrate.quad(lambda r: 2 * np.pi * r * burley_reflectance(r, albedo, length), 0, np.inf,
                                   limit=200)
        first, _ = integrate.quad(lambda r: 2 * np.pi * r * r * burley_reflectance(r, albedo, length), 0, np.inf,
                                  limit=200)
        assert zeroth == pytest.approx(albedo, rel=1e-7)
        assert first / zeroth == pytest.approx(float(burley_mean_radius_mm(albedo, length)), rel=1e-7)
    assert burley_scaling_factor(0.8) == pytest.approx(1.1)


def test_bad_media_are_refused():
    with pytest.raises(DermisError, match="sigma_a"):
        Medium(-0.1, 1.0)
    with pytest.raises(DermisError, match="anisotropy"):
        Medium(0.1, 1.0, g=1.0)
    with pytest.raises(DermisError, match="thickness"):
        Layer(MEDIA[0], 0.0)
