"""[environment] rotation: the HDR turned about the up axis (+y), read the same way by the SH
irradiance, the prefiltered specular (GL), the offline reference and the Blender export
(tests/test_blender_cycles.py: test_equirect_rotation_matches_dermis). Convention
(dermis.environment.rotate_equirect): what was seen along d is seen along R_y(theta) d."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_environment_specular import _highlight_centroid, _predicted_pixel, direction_deg, env_sphere_scene, \
    rectangle_hdr, smooth_hdr

import dermis
from dermis.environment import environment_sh, irradiance_sh_eval, rotate_equirect
from dermis.errors import DermisError
from dermis.renderer import Renderer
from dermis.scene.model import Environment, Texture
from dermis.techniques.shared import OutputMode

REPO = Path(__file__).resolve().parent.parent


def r_y(deg):
    t = math.radians(deg)
    return np.array([[math.cos(t), 0.0, math.sin(t)], [0.0, 1.0, 0.0], [-math.sin(t), 0.0, math.cos(t)]])


def test_the_reflection_turns_with_the_scene_parameter(gl_ctx):
    """A smooth sphere (m = 0.05) in a dark studio with one bright rectangle: with rotation 0, 90
    and 37 degrees set on the SAME renderer's scene, the highlight's centroid lies within 1.5 px of
    the closed-form mirror point of R_y(theta) times the rectangle's direction (37 degrees is not
    a whole number of columns: interpolated)."""
    size = (96, 96)
    env = Environment(image=Texture(rectangle_hdr(), "rect.exr", wrap=("repeat", "clamp")), color=(0, 0, 0),
                      occlusion=False)
    scene = env_sphere_scene(env, 0.05)
    centre = direction_deg(150.0, 25.0)
    errors = []
    with Renderer(scene, size, ctx=gl_ctx, samples=0, irradiance_size=128, shadow_size=256) as r:
        for theta in (0.0, 90.0, 37.0):
            scene.environment.rotation_deg = theta
            spec = r.render("preintegrated", output_mode=OutputMode.SPECULAR)
            got = _highlight_centroid(spec)
            want = _predicted_pixel(scene, size, r_y(theta) @ centre)
            errors.append(float(np.linalg.norm(got - want)))
    print(f"highlight vs mirror point (px) at 0, 90, 37 degrees: {np.round(errors, 2)}")
    assert max(errors) < 1.5, errors


def test_sh_irradiance_turns_with_the_environment():
    """E_theta(n) = E(R_y(-theta) n) for the SH irradiance (independent of the roll: the SH of
    the unturned image evaluated at turned normals), for a whole number of columns."""
    img = smooth_hdr(32, 64)
    theta = 360.0 / 64 * 11
    e0 = environment_sh(Environment(image=Texture(img, "s.exr")))
    e1 = environment_sh(Environment(image=Texture(img, "s.exr"), rotation_deg=theta))
    rng = np.random.default_rng(3)
    n = rng.normal(size=(500, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    a = irradiance_sh_eval(e1, n)
    b = irradiance_sh_eval(e0, n @ r_y(-theta).T)
    assert np.allclose(a, b, rtol=1e-4, atol=1e-6)
    assert not np.allclose(a, irradiance_sh_eval(e0, n), rtol=1e-2)  # the turn is visible


def test_reference_reads_the_turned_image():
    from dermis.reference.sampling import SurfaceModel

    sc = dermis.load_scene(REPO / "examples" / "reference" / "environment.toml")
    sc.environment.rotation_deg = 45.0
    model = SurfaceModel(sc)
    want = rotate_equirect(sc.environment.image.data[..., :3], 45.0) * sc.environment.intensity
    assert np.allclose(model.env_image, want, rtol=1e-6)


def test_toml_rotation(tmp_path):
    ex = (REPO / "examples").as_posix()
    src = (REPO / "examples" / "reference" / "environment.toml").read_text()
    text = src.replace('"../', f'"{ex}/').replace('image = "studio.exr"',
                                                  f'image = "{ex}/reference/studio.exr"\nrotation = 30.0')
    assert "rotation = 30.0" in text
    f = tmp_path / "rotated.toml"
    f.write_text(text)
    assert dermis.load_scene(f).environment.rotation_deg == 30.0
    f.write_text(text.replace("rotation = 30.0", 'rotation = "left"'))
    with pytest.raises(DermisError, match=r"\[environment\] rotation must be a finite number"):
        dermis.load_scene(f)
