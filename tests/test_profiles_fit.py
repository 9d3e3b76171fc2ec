"""The sum-of-Gaussians fitter: its error measure, d'Eon's table, the fair-skin profile."""

from __future__ import annotations

import numpy as np
import pytest

from dermis.errors import DermisError
from dermis.profiles.fit import fit_sum_of_gaussians, relative_l2_error
from dermis.profiles.gaussians import DEON_VARIANCES_MM2, DEON_WEIGHTS_RGB, gaussian_2d
from dermis.profiles.models import deon_profile, skin_profile
from dermis.profiles.presets import SKIN_PRESETS


def test_error_measure_matches_its_closed_form_for_two_gaussians():
    # integral_0^inf r G_a G_b dr = 1 / (4 pi^2 (a + b)), so the error of G_b against G_a is closed form
    a, b = 1.0, 1.2
    radius = (np.arange(20000) + 0.5) * (20.0 / 20000)
    numeric = relative_l2_error(radius, gaussian_2d(b, radius), gaussian_2d(a, radius))[0]
    cross = lambda x, y: 1.0 / (4 * np.pi**2 * (x + y))  # noqa: E731
    exact = np.sqrt((cross(a, a) + cross(b, b) - 2 * cross(a, b)) / cross(a, a))
    assert numeric == pytest.approx(exact, rel=1e-6)


def test_refitting_deon_from_its_own_curve_recovers_its_weights():
    profile = deon_profile()
    fixed = fit_sum_of_gaussians(profile, 6, variances_mm2=DEON_VARIANCES_MM2)
    assert np.max(np.abs(fixed.profile.weights - DEON_WEIGHTS_RGB)) < 0.01
    assert fixed.relative_error < 1e-3
    # with the variances free as well the optimiser reaches an (almost) equally good fit
    free = fit_sum_of_gaussians(profile, 6)
    assert free.relative_error < 0.01
    np.testing.assert_allclose(free.total_reflectance_rgb, 1.0, atol=2e-3)


def test_fair_skin_six_gaussian_fit_error_is_at_most_two_percent():
    profile = skin_profile(SKIN_PRESETS["fair"], "pbd")
    fit = fit_sum_of_gaussians(profile, 6)
    print("fair-skin K=6 errors", fit.relative_error_rgb, "variances", fit.profile.variances_mm2)
    assert fit.relative_error <= 0.02
    assert np.all(np.diff(fit.profile.variances_mm2) > 0)
    assert np.all(fit.profile.weights >= 0)
    # the weights carry the skin's colour: they sum to the total diffuse reflectance
    np.testing.assert_allclose(fit.total_reflectance_rgb, profile.total_reflectance_rgb, rtol=2e-3)
    # more Gaussians fit better, fewer worse
    assert fit_sum_of_gaussians(profile, 3).relative_error > fit.relative_error


@pytest.mark.parametrize("k", [0, -1, 17, 2.5, True])
def test_bad_numbers_of_gaussians_are_refused(k):
    with pytest.raises(DermisError, match="Gaussians"):
        fit_sum_of_gaussians(deon_profile(), k)
