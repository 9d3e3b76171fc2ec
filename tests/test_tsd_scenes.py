"""Texture-space diffusion on whole scenes: translucency, seams, and the real head."""

from __future__ import annotations

import numpy as np
import pytest

import dermis
from dermis.renderer import Renderer
from dermis.scene.builtin import cylinder_seam
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Environment, Light, Scene, SkinMaterial
from dermis.verification import backlit_slab_scene


def test_translucency_follows_the_thin_slab_law(gl_ctx):
    """A skin-coloured slab lit from behind: the light transmitted to the front falls with
    thickness d as the thin-slab law T(d) of dermis.profiles.thin_slab (diffusion theory of the
    medium the profile describes; tests/test_slab_theory.py holds it against the Monte Carlo),
    per channel, within 5% + 1e-4, for 0.5-5 mm."""
    from dermis.profiles.thin_slab import slab_law
    from dermis.verification import SKIN_ALBEDO

    law = slab_law(dermis.profiles.deon_skin(), np.array(SKIN_ALBEDO))
    measured, expected = [], []
    for d in (0.5, 1.0, 2.0, 3.0, 4.0, 5.0):
        sc = backlit_slab_scene(d, albedo=SKIN_ALBEDO)
        with Renderer(sc, (48, 48), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
            img = r.render("tsd", output_mode=1)
        front = img[20:28, 20:28].reshape(-1, 3).mean(axis=0)
        # lit side: E = pi (N.L = 1); front radiance = E T / pi = T (the albedo is in T)
        measured.append(front)
        expected.append(law.transmittance(d))
    measured, expected = np.array(measured), np.array(expected)
    assert np.all(np.abs(measured - expected) <= 0.05 * expected + 1e-4), f"{measured}\nvs\n{expected}"
    # red carries through, blue does not (the wide Gaussians are red): a 2 mm slab glows red
    assert measured[2, 0] > 10 * max(measured[2, 2], 1e-6)
    # monotone in thickness
    assert np.all(np.diff(measured[:, 0]) < 0)


def test_no_seam_line_across_lit_cylinder(gl_ctx):
    """A cylinder whose UV seam runs across the lit side (facing light and camera): the
    luminance on the seam is within 2% of its neighbours'."""
    p, n, uv, t = cylinder_seam(radius=10.0, height=30.0, nu=128, nv=16)
    mesh = finish_mesh(p, n, uv, t, "test:cylinder", "v-up")
    sc = Scene(mesh=mesh, material=SkinMaterial(albedo_color=(0.8, 0.6, 0.5), rho_s=0.0, pore_strength=0.0),
               lights=[Light(direction=(0.0, 0.0, -1.0), intensity=np.pi, cast_shadows=True)],
               camera=Camera(position=(0.0, 0.0, 150.0), fov_deg=14.0),
               environment=Environment(color=(0.02, 0.02, 0.02)), mm_per_unit=1.0)
    W = 128
    with Renderer(sc, (W, W), irradiance_size=256, ctx=gl_ctx, samples=0) as r:
        img = r.render("tsd")
        lam = r.render("lambert")
    lum = img @ np.array([0.2126, 0.7152, 0.0722])
    # the seam (azimuth 0) projects to the image's centre column; compare with columns 3-6 px away
    c = W // 2
    rows = slice(W // 2 - 20, W // 2 + 20)
    seam = lum[rows, c - 1:c + 1].mean(axis=1)
    neigh = np.concatenate([lum[rows, c - 6:c - 3], lum[rows, c + 3:c + 6]], axis=1).mean(axis=1)
    rel = np.abs(seam / neigh - 1)
    assert rel.max() < 0.02, f"seam deviates by {rel.max():.3%}"
    # sanity: the cylinder is lit there and tsd keeps it about as bright as lambert (no dark seam)
    lam_lum = lam @ np.array([0.2126, 0.7152, 0.0722])
    assert lum[rows, c].mean() > 0.5 * lam_lum[rows, c].mean() > 0


@pytest.fixture(scope="module")
def head_scene(example_head_toml):
    return dermis.load_scene(example_head_toml)


def test_head_backlit_ears_transmit_red(head_scene, gl_ctx):
    """Lit from behind, the ears glow: translucency adds light there, and it is red."""
    sc = head_scene
    sc.lights = [Light(direction=(0.0, -0.1, 1.0), intensity=6.0)]  # from behind the head
    sc.environment = Environment(color=(0.0, 0.0, 0.0))
    sc.camera = Camera(position=(9.0, 1.8, 3.0), target=(0.0, 1.8, 0.0), fov_deg=22.0)  # the right ear, from the side
    with Renderer(sc, (160, 160), irradiance_size=512, ctx=gl_ctx, samples=0) as r:
        with_t = r.render("tsd", output_mode=1)
        r.technique("tsd", translucency=False)
        without = r.render("tsd", output_mode=1)
    diff = with_t - without
    glow = diff.sum(axis=2) > 1e-3
    assert glow.sum() > 20, f"only {glow.sum()} pixels receive transmitted light"
    r_, g_, b_ = diff[glow].sum(axis=0)
    assert r_ > 3 * g_ and r_ > 3 * b_, (r_, g_, b_)


@pytest.mark.parametrize("key, bad", [("interreflection", '"yes"'), ("directional_albedo", "1"),
                                      ("translucency_light_path", '"on"')])
def test_scene_bool_key_default_off_and_a_bad_value_is_named(tmp_path, key, bad):
    """A [scene] switch: on by default where the code says so, off when the file says false, and a
    value that is not a bool named in one DermisError."""
    from dermis.errors import DermisError

    body = '\nmm_per_unit = 1.0\n[mesh]\nbuiltin = "plane"\n'
    (tmp_path / "default.toml").write_text("[scene]" + body)
    (tmp_path / "off.toml").write_text(f"[scene]\n{key} = false" + body)
    (tmp_path / "bad.toml").write_text(f"[scene]\n{key} = {bad}" + body)
    assert getattr(dermis.load_scene(tmp_path / "default.toml"), key) is Scene.__dataclass_fields__[key].default
    assert getattr(dermis.load_scene(tmp_path / "off.toml"), key) is False
    with pytest.raises(DermisError, match=rf"\[scene\] {key} must be a bool"):
        dermis.load_scene(tmp_path / "bad.toml")
