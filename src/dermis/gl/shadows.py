"""Shadow maps for all lights in one depth-only atlas.

Tile i of the atlas is light i's map, sampled with hardware comparison (sampler2DShadow,
common/shadow.glsl). There is no colour target: translucency comes from the thickness bake's far
face (common/transmittance.glsl), not from a translucent shadow map (d'Eon & Luebke 2007, sec.
14.5.3), which round 4 stopped reading and round 5 removed.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from dermis.errors import DermisError
from dermis.gl.resources import mat_bytes, set_uniform
from dermis.gl.shaders import program
from dermis.techniques.shared import MAX_LIGHTS, Unit, bind_sampler


# common/shadow.glsl's SHADOW_FILTER_* (a light's kernel, SKIN_SHADOW_FILTERS)
SHADOW_FILTER_RUNTIME, SHADOW_FILTER_NONE, SHADOW_FILTER_PARABOLA, SHADOW_FILTER_BOX = -1, 0, 1, 2
# common/shadow.glsl's constants, which pcf_filter decides with (tests/test_shadow_pcf.py reads them from the shader)
PCF_DISC_SCALE = 1.307  # the disc's radius per unit of softness
PCF_GRID = 3  # taps per axis
PCF_FIT_INSET = 0.51  # the parabola fits the grid where a_par < PCF_GRID - PCF_FIT_INSET
PCF_FILTER_MARGIN = 1e-3
"""pcf_filter leaves a kernel to run time where a_par is this close (texels) to the fit: the shader's
float32 may round the other way there."""


def pcf_filter(cast_shadows: bool, softness: float) -> int:
    """The kernel common/shadow.glsl's shadow_pcf_at picks for a light of ``softness`` (shadow texels),
    known before the draw so that the light pass can be compiled for it (SKIN_SHADOW_FILTERS):
    NONE without a shadow map, PARABOLA where the variance-matched parabola's half-width
    a_par = sqrt(5 (R^2 / 4 + 1/12)), R = PCF_DISC_SCALE softness, fits the grid (< PCF_GRID - PCF_FIT_INSET),
    BOX where it does not; RUNTIME (the shader decides) for softness <= 0 (one tap) and within
    PCF_FILTER_MARGIN of the fit, where float32 rounding could decide otherwise."""
    if not cast_shadows:
        return SHADOW_FILTER_NONE
    R = PCF_DISC_SCALE * float(softness)
    if not R > 0.0:
        return SHADOW_FILTER_RUNTIME
    a_par = math.sqrt(5.0 * (0.25 * R * R + 1.0 / 12.0))
    fit = PCF_GRID - PCF_FIT_INSET
    if abs(a_par - fit) < PCF_FILTER_MARGIN:
        return SHADOW_FILTER_RUNTIME
    return SHADOW_FILTER_BOX if a_par >= fit else SHADOW_FILTER_PARABOLA


def normal_offset(softness: float, half_extent: float, tile_size: int) -> float:
    """Normal offset (scene units) against acne (King 2004): it must cover the PCF footprint.

    A PCF tap ``R`` texels away on a receiver at angle theta to the light reads the receiver's own
    depth ``R tan(theta)`` texels nearer; offsetting along N by ``o`` clears it when
    o >= R sin(theta), so o = R texels with R = softness + 1.5 (disc + bilinear 2x2 + margin).
    A fixed 1.5 texels self-shadowed a lit sphere by up to 8% at N.L = 0.15 (softness 1.5).
    """
    texel_world = 2.0 * half_extent / tile_size
    return (max(float(softness), 0.0) + 1.5) * texel_world


class ShadowAtlas:
    def __init__(self, ctx, tile_size: int = 1024, max_lights: int = MAX_LIGHTS):
        self.ctx = ctx
        self.tile_size = int(tile_size)
        self.cols = 4 if max_lights > 4 else max(1, min(max_lights, 2))
        self.rows = math.ceil(max_lights / self.cols)
        self.prog = program(ctx, "shadow/shadow.vert")  # depth only: no fragment shader
        self.occluder_prog = None  # non-skin surfaces (shadow/occluder.frag), compiled when a scene has any
        self._size = None
        self.depth = self.fbo = None
        self.tiles = np.zeros((max_lights, 4), np.float32)
        self.params = np.zeros((max_lights, 4), np.float32)

    def _grid(self, n_lights) -> tuple[int, int]:
        """(columns, rows) of tiles in the atlas for ``n_lights``."""
        cols = min(self.cols, max(n_lights, 1))
        return cols, max(1, math.ceil(max(n_lights, 1) / cols))

    def _texture_limit(self) -> int:
        return int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE") or 16384)

    def max_tile_size(self, n_lights) -> int:
        """The largest power-of-two tile whose atlas for ``n_lights`` fits this GPU's texture limit."""
        return 1 << int(math.floor(math.log2(max(self._texture_limit() // max(self._grid(n_lights)), 1))))

    def _ensure(self, n_lights):
        cols, rows = self._grid(n_lights)
        size = (cols * self.tile_size, rows * self.tile_size)
        if size == self._size:
            return
        limit = self._texture_limit()
        if max(size) > limit:
            raise DermisError(f"shadow_size: {self.tile_size} per light: {n_lights} lights need a {size[0]}x{size[1]} shadow "
                              f"atlas, over this GPU's texture limit of {limit}; use a smaller shadow_size")
        self._release_targets()
        self._size = size
        self.depth = self.ctx.depth_texture(size)
        self.depth.compare_func = "<="
        self.depth.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.depth.repeat_x = self.depth.repeat_y = False
        self.fbo = self.ctx.framebuffer(depth_attachment=self.depth)
        self.grid = (cols, rows)

    def render(self, gpu_scene, light_uniforms):
        """Render every light's tile. Returns the number of tiles drawn."""
        n = light_uniforms.count
        self._ensure(n)
        cols, rows = self.grid
        W, H = self._size
        self.fbo.use()
        self.fbo.clear(depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)  # thin parts: both faces occlude
        vao = gpu_scene.vao(self.prog)
        surfaces = getattr(gpu_scene, "surfaces", [])
        if surfaces and self.occluder_prog is None:
            self.occluder_prog = program(self.ctx, "common/mesh.vert", "shadow/occluder.frag")
        self.update_params(light_uniforms)
        for i, L in enumerate(light_uniforms.lights):
            c, r = i % cols, i // cols
            if not L.cast_shadows:
                continue
            self.fbo.viewport = (c * self.tile_size, r * self.tile_size, self.tile_size, self.tile_size)
            set_uniform(self.prog, "uViewProj", mat_bytes(light_uniforms.viewproj[i]))
            vao.render(moderngl.TRIANGLES)
            if surfaces:  # non-skin surfaces occlude too
                set_uniform(self.occluder_prog, "uViewProj", mat_bytes(light_uniforms.viewproj[i]))
                for s in surfaces:
                    s.uniforms(self.occluder_prog)
                    s.vao(self.occluder_prog).render(moderngl.TRIANGLES)
        return sum(1 for L in light_uniforms.lights if L.cast_shadows)

    def update_params(self, light_uniforms):
        """Tile placement and filtering parameters of each light (cheap; every frame)."""
        self._ensure(light_uniforms.count)
        cols, rows = self.grid
        for i, L in enumerate(light_uniforms.lights):
            c, r = i % cols, i // cols
            self.tiles[i] = (c / cols, r / rows, 1.0 / cols, 1.0 / rows)
            offset = normal_offset(L.shadow_softness, light_uniforms.map_half_extent[i], self.tile_size)
            self.params[i] = (L.shadow_softness, L.shadow_bias, offset, 1.0 / self.tile_size)

    def bind(self, prog):
        """The atlas at its contract unit, and each tile's parameters."""
        bind_sampler(prog, "uShadowAtlas", self.depth, Unit.SHADOW_ATLAS)
        set_uniform(prog, "uShadowTile", self.tiles)
        set_uniform(prog, "uShadowParams", self.params)

    def _release_targets(self):
        for o in (self.fbo, self.depth):
            if o is not None:
                o.release()
        self.fbo = self.depth = None
        self._size = None

    def release(self):
        self._release_targets()
        for name in ("prog", "occluder_prog"):
            if getattr(self, name) is not None:
                getattr(self, name).release()
                setattr(self, name, None)
