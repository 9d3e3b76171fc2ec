"""On the real head, every skin technique reddens shadow penumbras compared with lambert:
light scatters into the shadow, red furthest."""

from __future__ import annotations

import numpy as np
import pytest

import dermis
from dermis.renderer import Renderer
from dermis.scene.model import Environment, Light


@pytest.fixture(scope="module")
def penumbra_renders(example_head_toml, gl_ctx):
    sc = dermis.load_scene(example_head_toml)
    sc.lights = [Light(direction=(0.75, -0.25, -0.6), intensity=4.0, shadow_softness=2.0)]
    sc.environment = Environment(color=(0.01, 0.01, 0.01))
    out = {}
    with Renderer(sc, (256, 256), irradiance_size=512, ctx=gl_ctx, samples=0) as r:
        for name in ("lambert", "tsd", "ssss", "preintegrated"):
            out[name] = r.render(name)
        sc.lights[0].cast_shadows = False
        out["lambert_unshadowed"] = r.render("lambert")
    ratio = out["lambert"].sum(axis=2) / np.maximum(out["lambert_unshadowed"].sum(axis=2), 1e-6)
    lit = out["lambert_unshadowed"].sum(axis=2) > 0.05
    out["penumbra"] = lit & (ratio > 0.1) & (ratio < 0.6)
    return out


@pytest.mark.parametrize("technique", ["tsd", "ssss", "preintegrated"])
def test_head_penumbra_is_redder_than_lambert(penumbra_renders, technique):
    pen = penumbra_renders["penumbra"]
    assert pen.sum() > 30, f"only {pen.sum()} penumbra pixels"
    img, lam = penumbra_renders[technique], penumbra_renders["lambert"]
    rg = img[pen, 0].sum() / img[pen, 1].sum()
    rg_lam = lam[pen, 0].sum() / lam[pen, 1].sum()
    assert rg > rg_lam * 1.05, (technique, rg, rg_lam)
