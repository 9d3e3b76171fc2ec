"""The shadow atlas and its percentage-closer filtering (common/shadow.glsl, gl/shadows.py)."""

from __future__ import annotations

import moderngl

from dermis.renderer import Renderer
from dermis.scene.builtin import box_over_plane
from dermis.scene.loaders import finish_mesh
from dermis.scene.model import Camera, Light, Scene, SkinMaterial


def _box_scene(direction=(0.3, 0.2, -1.0), softness=1.5):
    p, n, uv, t = box_over_plane()
    mesh = finish_mesh(p, n, uv, t, "builtin:box_over_plane", "v-up")
    return Scene(mesh=mesh, material=SkinMaterial(rho_s=0.0),
                 lights=[Light(kind="directional", direction=direction, intensity=3.0, shadow_softness=softness)],
                 camera=Camera(position=(1.0, 1.3, 2.4), target=(0.25, 0.15, 0.0), fov_deg=40.0))


def test_shadow_pass_is_depth_only(gl_ctx):
    """No translucent-shadow-map colour target: the pass writes the depth atlas and nothing else."""
    with Renderer(_box_scene(), (32, 32), ctx=gl_ctx, samples=0) as r:
        r.render("lambert")
        atlas = r.shadows
        assert atlas.fbo.color_attachments == () and atlas.fbo.depth_attachment is atlas.depth
        assert not hasattr(atlas, "aux")
        assert set(r.debug_buffers("lambert")) & {"shadow_tsm"} == set()
