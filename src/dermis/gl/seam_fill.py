"""tsd's seam fill on the GPU (dermis.geometry.seams): per blur step, the gutter texels of the step's
input beside UV seams overwritten, in place, with the input read at the same surface point in the
neighbouring chart (shaders/tsd/seam_fill.*), so the step's Gaussian gathers light across the seam.
The targets are found once per layout, size and reach on the CPU (cached) and kept per level as two
textures (the taps' texel and the distance from the seam, RG32F; the taps' weights, RGBA8); a step
draws the TILE x TILE tiles holding fill texels, each texel within the step's reach filled, the
rest discarded. Tiles, not a point per texel: llvmpipe shades every primitive as whole 4 x 4 blocks,
and points cost 0.3-0.5 us each (the head's ~60 k fill texels a frame: ~22 ms of a ~95 ms chain);
a copy of the input per step (a blit, so as not to read the texture drawn into) cost as much again.
In place: the taps never lie on a texel the fill writes (bilinear_taps)."""

from __future__ import annotations

import moderngl
import numpy as np

from dermis.gl.shaders import program

TILE = 8  # texels per tile side (16: 7.7 ms of fills a frame on the head, 8: 7.1, 4: 9.6)
NONE = 1e30  # the distance of a texel with nothing to fill


class SeamFill:
    def __init__(self, ctx):
        self.ctx = ctx
        self._prog = None
        self.key = None
        self._levels = {}  # level -> (vertex array, vertex buffer, vertices, fill texture, weights texture)
        self._distances = {}  # level -> the fill texels' distances from their seam (mesh units), ascending
        self.texels = {}  # level -> number of texels filled (reports)

    def release(self):
        for vao, buf, _, fill, weights in self._levels.values():
            vao.release()
            buf.release()
            fill.release()
            weights.release()
        self._levels = {}
        self._distances = {}
        self.texels = {}
        self.key = None

    def prepare(self, key, mesh, size: int, reach_texels: dict) -> bool:
        """Build the levels' textures and tiles for ``key`` (the layout, size and reaches); whether any
        texel is filled."""
        if key == self.key:
            return bool(self._levels)
        from dermis.geometry.seams import bilinear_taps, cached_fill_targets
        from dermis.geometry.texture_space import texture_space_uvs

        self.release()
        if self._prog is None:
            self._prog = program(self.ctx, "tsd/seam_fill.vert", "tsd/seam_fill.frag", {})
        got = cached_fill_targets(mesh.positions, mesh.indices, texture_space_uvs(mesh), size, reach_texels)
        for L, (texels, targets, distances) in got.items():
            SL = max(int(size) >> int(L), 1)
            base, w = bilinear_taps(texels, targets, SL)
            keep = w.sum(1) > 0
            texels, base, w, distances = texels[keep], base[keep], w[keep], distances[keep]
            self.texels[L] = len(texels)
            if len(texels) == 0:
                continue
            self._distances[L] = np.sort(distances)
            fill = np.zeros((SL, SL, 2), np.float32)
            fill[..., 1] = NONE
            fill[texels[:, 1], texels[:, 0], 0] = base[:, 1].astype(np.float64) * SL + base[:, 0]
            fill[texels[:, 1], texels[:, 0], 1] = distances
            wt = np.zeros((SL, SL, 4), np.uint8)
            wt[texels[:, 1], texels[:, 0]] = np.round(w * 255.0).astype(np.uint8)
            fill_tex = self.ctx.texture((SL, SL), 2, fill.tobytes(), dtype="f4")
            w_tex = self.ctx.texture((SL, SL), 4, wt.tobytes(), dtype="f1")
            for t in (fill_tex, w_tex):
                t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            # the tiles holding fill texels, two triangles each, in clip space
            tiles = np.unique(texels // TILE, axis=0).astype(np.float64)
            x0, y0 = tiles[:, 0] * TILE / SL * 2 - 1, tiles[:, 1] * TILE / SL * 2 - 1
            x1, y1 = np.minimum(x0 + TILE / SL * 2, 1.0), np.minimum(y0 + TILE / SL * 2, 1.0)
            quads = np.stack([x0, y0, x1, y0, x1, y1, x0, y0, x1, y1, x0, y1], 1).reshape(-1, 2).astype(np.float32)
            buf = self.ctx.buffer(quads.tobytes())
            vao = self.ctx.vertex_array(self._prog, [(buf, "2f", "in_position")])
            self._levels[L] = (vao, buf, len(quads), fill_tex, w_tex)
        self.key = key
        return bool(self._levels)

    def filled(self, level: int) -> bool:
        return level in self._levels

    def count(self, level: int, reach) -> int:
        """The level's fill texels within ``reach`` (mesh units) of their seam."""
        d = self._distances.get(level)
        return 0 if d is None else int(np.searchsorted(d, reach, side="right"))

    def draw(self, tex, fbo, level: int, reach: float):
        """Fill the level's seam texels of ``tex`` within ``reach`` (mesh units) of their seam (drawn
        through ``fbo``, whose only target ``tex`` is)."""
        vao, _, n, fill, weights = self._levels[level]
        fbo.use()
        tex.use(0)
        fill.use(1)
        weights.use(2)
        prog = self._prog
        prog["uSource"].value = 0
        prog["uFill"].value = 1
        prog["uWeights"].value = 2
        prog["uReach"].value = float(reach)
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        vao.render(moderngl.TRIANGLES, vertices=n)
