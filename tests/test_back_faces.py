"""[material] double_sided = false: the screen-space passes skip the skin's back faces.

References (geometry, not dermis): a closed sphere wound counter-clockwise seen from outside has
every back face behind a front face, so skipping them changes no pixel whose samples all see the
sphere; an open quad seen from behind shows only back faces, so none of it is drawn.
"""

from __future__ import annotations

import numpy as np
import pytest

import dermis
from dermis.errors import DermisError
from dermis.renderer import Renderer
from dermis.verification import quad_scene

SPHERE = """
[scene]
mm_per_unit = 20.0
[mesh]
builtin = "sphere"
[material]
double_sided = {ds}
[[lights]]
type = "directional"
direction = [0.5, -0.6, -0.6]
intensity = 3.0
[camera]
position = [0.0, 0.5, 4.0]
target = [0.0, 0.0, 0.0]
[output]
background = [0.0, 0.0, 0.0]
"""


def _sphere(tmp_path, ds: str):
    p = tmp_path / f"sphere_{ds}.toml"
    p.write_text(SPHERE.format(ds=ds))
    return dermis.load_scene(p)


def test_closed_skin_renders_the_same_without_its_back_faces(gl_ctx, tmp_path):
    both, front = _sphere(tmp_path, "true"), _sphere(tmp_path, "false")
    assert both.material.double_sided is True and front.material.double_sided is False
    with Renderer(both, (64, 64), irradiance_size=64, ctx=gl_ctx, samples=4) as r:
        a = r.render("lambert", with_alpha=True)
        r.set_scene(front)
        b = r.render("lambert", with_alpha=True)
    inside = (a[..., 3] == 1.0) & (b[..., 3] == 1.0)  # every sample on the sphere
    assert inside.sum() > 500
    np.testing.assert_array_equal(a[inside], b[inside])
    # silhouette pixels (partly covered) may differ by the samples a back face covered
    assert np.count_nonzero(np.any(a != b, axis=-1)) <= np.count_nonzero((a[..., 3] > 0) & (a[..., 3] < 1)) + 8


def test_an_open_sheet_seen_from_behind_is_not_drawn_single_sided(gl_ctx):
    sc = quad_scene(40.0, 40.0)
    sc.camera.position = (0.0, 0.0, -120.0)  # behind the quad (its normals face +z)
    sc.camera.target = (0.0, 0.0, 0.0)
    with Renderer(sc, (32, 32), irradiance_size=64, ctx=gl_ctx, samples=0) as r:
        seen = r.render("lambert", with_alpha=True)
        sc.material.double_sided = False
        culled = r.render("lambert", with_alpha=True)
    assert seen[..., 3].sum() > 100  # double-sided (the default): the quad covers the view's middle
    assert culled[..., 3].max() == 0.0


def test_double_sided_must_be_a_boolean(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text(SPHERE.format(ds='"no"'))
    with pytest.raises(DermisError, match="double_sided"):
        dermis.load_scene(p)
