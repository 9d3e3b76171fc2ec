"""tsd's seam fill on the GPU (dermis.geometry.seams): per blur step, the step's input copied and its
gutter texels beside UV seams overwritten with the input read at the same surface point in the
neighbouring chart (shaders/tsd/seam_fill.*: one point per texel), so the step's Gaussian gathers
light across the seam. The targets are found once per layout, size and reach on the CPU (cached)."""

from __future__ import annotations

import moderngl
import numpy as np

from dermis.gl.shaders import program


class SeamFill:
    def __init__(self, ctx):
        self.ctx = ctx
        self._prog = None
        self.key = None
        self._levels = {}  # level -> (vertex array, buffer, point count)
        self.texels = {}  # level -> number of texels filled (reports)

    def release(self):
        for vao, buf, _ in self._levels.values():
            vao.release()
            buf.release()
        self._levels = {}
        self.texels = {}
        self.key = None

    def prepare(self, key, mesh, size: int, reach_texels: dict) -> bool:
        """Build the levels' point lists for ``key`` (the layout, size and reaches); whether any
        texel is filled."""
        if key == self.key:
            return any(n for _, _, n in self._levels.values())
        from dermis.geometry.seams import cached_fill_targets
        from dermis.geometry.texture_space import texture_space_uvs

        self.release()
        if self._prog is None:
            self._prog = program(self.ctx, "tsd/seam_fill.vert", "tsd/seam_fill.frag", {})
        got = cached_fill_targets(mesh.positions, mesh.indices, texture_space_uvs(mesh), size, reach_texels)
        for L, (texels, targets) in got.items():
            self.texels[L] = len(texels)
            if len(texels) == 0:
                continue
            data = np.ascontiguousarray(np.c_[texels.astype(np.float32), targets], np.float32)
            buf = self.ctx.buffer(data.tobytes())
            vao = self.ctx.vertex_array(self._prog, [(buf, "2f 2f", "in_texel", "in_target")])
            self._levels[L] = (vao, buf, len(texels))
        self.key = key
        return any(n for _, _, n in self._levels.values())

    def filled(self, level: int) -> bool:
        return level in self._levels

    def draw(self, src, dst, src_fbo, dst_fbo, level: int):
        """dst = src with the level's seam texels filled (dst and src of one size)."""
        vao, _, n = self._levels[level]
        self.ctx.copy_framebuffer(dst_fbo, src_fbo)
        dst_fbo.use()
        src.use(0)
        self._prog["uSource"].value = 0
        self._prog["uSize"].value = tuple(float(s) for s in dst.size)
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        vao.render(moderngl.POINTS, vertices=n)
