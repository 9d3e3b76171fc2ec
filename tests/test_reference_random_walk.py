"""The random walk inside a mesh (dermis.reference.random_walk) against MCML (dermis.profiles.monte_carlo)
on a closed slab (a box 60 x 60 x 1 mm), for both boundary models. About 10 s on 2 cores.

Reciprocity ties the two: the walk estimates the radiance leaving one face towards a camera; MCML
the power leaving per unit power entering. With camera directions drawn cosine-distributed over the
face's hemisphere, pi x the mean radiance is the face's exitance M, and for a directional light of
irradiance E at cos theta_l, M = E cos theta_l (1 - F(theta_l)) x MCML's R or T (index 1.4, the beam
refracted in). The walk's directions never meet MCML's unscattered beam (a delta along the beam):
its closed form, (1 - F) e / (1 - F^2 e^2) with e = exp(-d / (mfp cos theta_t)), is taken off T.
Cycles' walk (Lambertian gather, index-matched, seen head-on) gives pi L / E = MCML's R or T of an
index-matched slab launched along the normal.
"""

from __future__ import annotations

import numpy as np
import pytest

from dermis.errors import DermisError
from dermis.geometry.raycast import cosine_directions
from dermis.profiles.medium import Layer, Medium
from dermis.profiles.monte_carlo import monte_carlo_reflectance
from dermis.reference.random_walk import DirectionalLight, MeshWalk, WalkMedium, fresnel_unpolarised
from dermis.scene.builtin import slab

THICKNESS_MM, MFP_MM, ALBEDO = 1.0, 0.5, 0.95
WALKS, PHOTONS = 4000, 40_000


@pytest.fixture(scope="module")
def slab_walk():
    p, nn, _, t = slab(size=60.0, thickness=THICKNESS_MM, n=4)
    mw = MeshWalk(p, t, nn)
    rng = np.random.default_rng(3)
    # start points on the front face (z = +d/2) within 1 mm of the centre, and their triangles
    pts = np.c_[rng.uniform(-1, 1, (WALKS, 2)), np.full(WALKS, THICKNESS_MM / 2)]
    _, tri, _ = mw.caster.closest_hit(pts + [0, 0, 1.0], np.tile([0, 0, -1.0], (WALKS, 1)))
    assert (tri >= 0).all()
    return mw, pts, tri


def _mcml(index, incidence_cos=1.0):
    m = Medium(np.array([(1 - ALBEDO) / MFP_MM]), np.array([ALBEDO / MFP_MM]), 0.0, index)
    return monte_carlo_reflectance([Layer(m, THICKNESS_MM)], PHOTONS, [0.0, 1e3], seed=1, incidence_cos=incidence_cos)


def _close(walk, ref, ref_se):
    L = np.pi * walk
    se = np.hypot(L.std() / np.sqrt(len(L)), ref_se)
    assert abs(L.mean() - ref) < 4.0 * se, (L.mean(), ref, se)


@pytest.mark.parametrize("transmitted", [True, False], ids=["T", "R"])
def test_skin_walk_in_a_slab_mesh_is_mcml(slab_walk, transmitted):
    mw, pts, tri = slab_walk
    cos_l = 0.7  # an oblique light: the refracted entry search and the Fresnel factors
    light = DirectionalLight((np.sqrt(1 - cos_l ** 2), 0.0, -cos_l if transmitted else cos_l), 1.0)
    rng = np.random.default_rng(4)
    out = cosine_directions(np.tile([0, 0, 1.0], (WALKS, 1)), rng.random((WALKS, 1)), rng.random((WALKS, 1)))[:, 0]
    L = mw.radiance(pts, tri, -out, WalkMedium(MFP_MM, ALBEDO, "fresnel", 1.4), [light], seed=5)
    # the enumeration of facets as the light's source (the slab's facets are 15 mm wide: centroids within 40 mm)
    L_ex = mw.radiance(pts[:1000], tri[:1000], -out[:1000], WalkMedium(MFP_MM, ALBEDO, "fresnel", 1.4), [light],
                       seed=15, nee="exhaustive", check_radius_mm=40.0)
    r = _mcml(1.4, cos_l)
    F, cos_t = fresnel_unpolarised(np.array([cos_l]), 1.0, 1.4)
    if transmitted:
        f_in = fresnel_unpolarised(cos_t, 1.4, 1.0)[0][0]
        e = np.exp(-THICKNESS_MM / (MFP_MM * cos_t[0]))
        ref = r.total_transmittance - (1 - f_in) * e / (1 - f_in ** 2 * e * e)
        ref_se = np.sqrt(r.total_transmittance / PHOTONS)
    else:
        ref, ref_se = r.total_reflectance, r.total_reflectance_standard_error
    scale = cos_l * (1 - F[0])
    assert ref > 0.1
    _close(L, ref * scale, ref_se * scale)
    _close(L_ex, ref * scale, ref_se * scale)


@pytest.mark.parametrize("transmitted", [True, False], ids=["T", "R"])
def test_cycles_walk_in_a_slab_mesh_is_index_matched_mcml(slab_walk, transmitted):
    mw, pts, tri = slab_walk
    light = DirectionalLight((0.0, 0.0, -1.0 if transmitted else 1.0), 1.0)
    head_on = np.tile([0, 0, -1.0], (WALKS, 1))
    L = mw.radiance(pts, tri, head_on, WalkMedium(MFP_MM, ALBEDO, "lambertian", 1.4), [light], seed=6)
    r = _mcml(1.0)
    ref = r.total_transmittance if transmitted else r.total_reflectance
    _close(L, ref, np.sqrt(ref / PHOTONS))


def test_environment_alone_through_a_slab(slab_walk):
    """A uniform environment of radiance C around a non-absorbing slab: every walk leaves, so the
    radiance is C for both boundaries (energy conservation; the Fresnel n^2 factors cancel)."""
    mw, pts, tri = slab_walk
    head_on = np.tile([0, 0, -1.0], (500, 1))
    for m in (WalkMedium(MFP_MM, 1.0, "fresnel", 1.4), WalkMedium(MFP_MM, 1.0, "lambertian", 1.4)):
        L = mw.radiance(pts[:500], tri[:500], head_on, m, environment=0.25, seed=7)
        F = fresnel_unpolarised(np.array([1.0]), 1.0, 1.4)[0][0] if m.boundary == "fresnel" else 0.0
        # the fresnel walk's radiance leaving is (1 - F_o) of what is inside (the rest is the specular)
        assert L.mean() == pytest.approx(0.25 * (1 - F), abs=4 * L.std() / np.sqrt(len(L)) + 1e-9)


def test_bad_medium_is_refused():
    with pytest.raises(DermisError, match="boundary"):
        WalkMedium(1.0, 0.9, "mirror")
    with pytest.raises(DermisError, match="mean free path"):
        WalkMedium(0.0, 0.9)


def test_refracted_beam_inside_a_slab_is_the_closed_form(slab_walk):
    """The light's collimated source at points inside the slab, by the refracted-entry search and by
    the enumeration of facets: E (1 - F) cos_l / cos_t exp(-s / mfp), s the path from the back face
    along the refracted beam (depth / cos_t)."""
    mw, _, _ = slab_walk
    rng = np.random.default_rng(8)
    depth = rng.uniform(0.05, 0.95, 200) * THICKNESS_MM  # from the back face (z = -d/2)
    y = np.c_[rng.uniform(-2, 2, (200, 2)), depth - THICKNESS_MM / 2]
    cos_l = 0.4
    light = DirectionalLight((np.sqrt(1 - cos_l ** 2), 0.0, -cos_l), 2.0)
    F, cos_t = fresnel_unpolarised(np.array([cos_l]), 1.0, 1.4)
    expected = 2.0 * (1 - F[0]) * cos_l / cos_t[0] * np.exp(-depth / cos_t[0] / MFP_MM)
    e_in, dist, found = mw._beam_at(y, light, 1.4)
    assert found.all()
    np.testing.assert_allclose(e_in * np.exp(-dist / MFP_MM), expected, rtol=1e-6)
    # the slab's facets are 15 mm wide: enumerate those with centroids within 40 mm
    np.testing.assert_allclose(mw.beam_exhaustive(y, light, 1.4, MFP_MM, 40.0), expected, rtol=1e-6)


def test_bounce_is_what_the_surface_met_sends_back():
    """A second box 4 mm above the slab's lit face: a leaving ray that meets it gets the ``bounce``
    callback's radiance instead of the environment's. With both 0.25 and a non-absorbing medium the
    walk returns 0.25 (1 - F) exactly (as the environment alone); with the box sending back nothing
    the result drops by the share of rays that meet it (about half of the walks leave through the
    lit face, and most of those meet the box)."""
    p, nn, _, t = slab(size=60.0, thickness=THICKNESS_MM, n=4)
    p2 = p + [0.0, 0.0, 5.0]
    mw = MeshWalk(np.r_[p, p2], np.r_[t, t + len(p)], np.r_[nn, nn])
    pts = np.tile([0.0, 0.0, THICKNESS_MM / 2], (300, 1))
    _, tri, _ = mw.caster.closest_hit(pts - [0, 0, 0.1], np.tile([0, 0, 1.0], (300, 1)))
    head_on = np.tile([0, 0, -1.0], (300, 1))
    m = WalkMedium(MFP_MM, 1.0, "fresnel", 1.4)
    F = fresnel_unpolarised(np.array([1.0]), 1.0, 1.4)[0][0]
    calls = []

    def same(points, triangles, bary, dirs):
        calls.append(len(points))
        assert (points[:, 2] > 4.0).all() and (dirs[:, 2] > 0).all()  # on the box above, rays going up
        return np.full(len(points), 0.25)

    L = mw.radiance(pts, tri, head_on, m, environment=0.25, seed=9, bounce=same)
    assert sum(calls) > 0
    np.testing.assert_allclose(L, 0.25 * (1 - F), rtol=1e-12)
    dark = mw.radiance(pts, tri, head_on, m, environment=0.25, seed=9, bounce=lambda *a: np.zeros(len(a[0])))
    assert 0.3 < dark.mean() / L.mean() < 0.75


def test_paths_say_which_face_the_light_entered(slab_walk):
    """Back-lit, every bit of the light entered through the far face (facing away from the start's);
    front-lit, none did; and the light-weighted entry distance is at least the thickness when back-lit."""
    mw, pts, tri = slab_walk
    head_on = np.tile([0, 0, -1.0], (500, 1))
    for z, opposite in ((-1.0, 1.0), (1.0, 0.0)):
        st = {}
        L = mw.radiance(pts[:500], tri[:500], head_on, WalkMedium(MFP_MM, ALBEDO, "fresnel", 1.4),
                        [DirectionalLight((0.0, 0.0, z), 1.0)], seed=11, stats=st, paths=True)
        p = st["paths"]
        np.testing.assert_allclose(p["light"], L, rtol=1e-12)
        assert p["opposite"].sum() == pytest.approx(opposite * L.sum(), rel=1e-12)
        if opposite:
            assert p["distance"].sum() / L.sum() >= THICKNESS_MM
