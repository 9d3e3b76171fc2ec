"""tsd's seam fill on the GPU (dermis.geometry.seams): per blur step, the gutter texels of the step's
input beside UV seams overwritten, in place, with the input read at the same surface point in the
neighbouring chart (shaders/tsd/seam_fill.*), so the step's Gaussian gathers light across the seam.
The targets are found once per layout, size and reach on the CPU (cached) and kept per level as two
textures (the taps' texel and the distance from the seam, RG32F; the taps' weights, RGBA8); a step
draws rectangles covering the TILE x TILE cells that hold its own fill texels (those within the step's
reach), each such texel filled, the rest discarded. All steps' rectangles lie in one vertex buffer,
each step drawing its own range (first, count).
Cost on llvmpipe (round 22, seamcost22, the scanned head at 1024^2): a fill's time is its primitives
and the 4 x 4 blocks it shades (llvmpipe shades every primitive as whole 4 x 4 blocks), not the
fills' arithmetic (a draw discarding every texel costs the same): a point per texel cost 0.3-0.5 us
each (~22 ms a frame), one 8 x 8 tile per quad of every fill texel of the level ~4.8 ms over the
five draws, 4 x 4 cells within the step's reach merged into rectangles ~3.1 ms (measured in
benchmarks/RESULTS.md "Round 22, branch seamcost22"). A copy of the input per step (a blit, so as
not to read the texture drawn into) cost as much again as the points.
In place: the taps never lie on a texel the fill writes (bilinear_taps)."""

from __future__ import annotations

import moderngl
import numpy as np

from dermis.gl.shaders import program

TILE = 4  # texels per cell side: llvmpipe's shading block (merged: 4: 3.1 ms of fills a frame on the head, 8: 3.5, 16: 4.9)
NONE = 1e30  # the distance of a texel with nothing to fill


def cell_rectangles(cells) -> np.ndarray:
    """(m, 4) int64 rectangles (x0, y0, x1, y1; x1, y1 exclusive) covering exactly the (n, 2) cells
    (x, y; duplicates allowed): each row's runs of adjacent cells, and runs of equal extent in
    consecutive rows joined (fewer primitives for llvmpipe to set up and bin)."""
    c = np.unique(np.asarray(cells, np.int64).reshape(-1, 2), axis=0)
    if len(c) == 0:
        return np.zeros((0, 4), np.int64)
    c = c[np.lexsort((c[:, 0], c[:, 1]))]  # by row, then column
    brk = np.r_[True, (np.diff(c[:, 0]) != 1) | (np.diff(c[:, 1]) != 0)]
    first = np.nonzero(brk)[0]
    last = np.r_[first[1:], len(c)] - 1
    out, open_ = [], {}  # (x0, x1) -> [x0, y0, x1, y1] still growing downwards
    for x0, y, x1 in zip(c[first, 0].tolist(), c[first, 1].tolist(), (c[last, 0] + 1).tolist()):
        r = open_.get((x0, x1))
        if r is not None and r[3] == y:
            r[3] = y + 1
        else:
            if r is not None:
                out.append(r)
            open_[(x0, x1)] = [x0, y, x1, y + 1]
    return np.array(out + list(open_.values()), np.int64)


class SeamFill:
    def __init__(self, ctx):
        self.ctx = ctx
        self._prog = None
        self.key = None
        self._levels = {}  # level -> (fill texture, weights texture)
        self._texels = {}  # level -> the fill texels (n, 2), by ascending distance
        self._distances = {}  # level -> the fill texels' distances from their seam (mesh units), ascending
        self._ranges = {}  # (level, fill texels drawn) -> (first vertex, vertex count) in the buffer
        self._steps = {}  # (level, reach) -> its range
        self._quads = []  # every range's vertices (clip space), in buffer order
        self._vao = self._buf = None
        self.texels = {}  # level -> number of texels filled (reports)

    def release(self):
        for fill, weights in self._levels.values():
            fill.release()
            weights.release()
        self._release_buffer()
        self._levels = {}
        self._texels = {}
        self._distances = {}
        self._ranges = {}
        self._steps = {}
        self._quads = []
        self.texels = {}
        self.key = None

    def _release_buffer(self):
        if self._vao is not None:
            self._vao.release()
            self._buf.release()
        self._vao = self._buf = None

    def prepare(self, key, mesh, size: int, reach_texels: dict) -> bool:
        """Build the levels' textures for ``key`` (the layout, size and reaches); whether any texel is
        filled."""
        if key == self.key:
            return bool(self._levels)
        from dermis.geometry.seams import bilinear_taps, cached_fill_targets
        from dermis.geometry.texture_space import texture_space_uvs

        self.release()
        if self._prog is None:
            self._prog = program(self.ctx, "tsd/seam_fill.vert", "tsd/seam_fill.frag", {})
            for name, unit in (("uSource", 0), ("uFill", 1), ("uWeights", 2)):  # fixed units: set once
                self._prog[name].value = unit
        got = cached_fill_targets(mesh.positions, mesh.indices, texture_space_uvs(mesh), size, reach_texels)
        for L, (texels, targets, distances) in got.items():
            SL = max(int(size) >> int(L), 1)
            base, w = bilinear_taps(texels, targets, SL)
            keep = w.sum(1) > 0
            texels, base, w, distances = texels[keep], base[keep], w[keep], distances[keep]
            self.texels[L] = len(texels)
            if len(texels) == 0:
                continue
            order = np.argsort(distances, kind="stable")  # (fill_targets sorts them: kept as a guard)
            self._texels[L], self._distances[L] = texels[order], distances[order]
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
            self._levels[L] = (fill_tex, w_tex)
        self.key = key
        return bool(self._levels)

    def filled(self, level: int) -> bool:
        return level in self._levels

    def count(self, level: int, reach) -> int:
        """The level's fill texels within ``reach`` (mesh units) of their seam."""
        d = self._distances.get(level)
        return 0 if d is None else int(np.searchsorted(d, reach, side="right"))

    def _range(self, level: int, n: int):
        """(first vertex, vertex count) of the rectangles covering the level's ``n`` nearest fill
        texels' cells; added to the buffer on first use (a plan's steps ask once, when prepared)."""
        got = self._ranges.get((level, n))
        if got is None:
            SL = self._levels[level][0].size[0]
            R = cell_rectangles(self._texels[level][:n] // TILE).astype(np.float64) * (TILE / SL * 2.0) - 1.0
            x0, y0, x1, y1 = R[:, 0], R[:, 1], np.minimum(R[:, 2], 1.0), np.minimum(R[:, 3], 1.0)
            quads = np.stack([x0, y0, x1, y0, x1, y1, x0, y0, x1, y1, x0, y1], 1).reshape(-1, 2).astype(np.float32)
            got = (sum(len(q) for q in self._quads), len(quads))
            self._quads.append(quads)
            self._ranges[(level, n)] = got
            self._release_buffer()
            self._buf = self.ctx.buffer(np.concatenate(self._quads).tobytes())
            self._vao = self.ctx.vertex_array(self._prog, [(self._buf, "2f", "in_position")])
        return got

    def prepare_step(self, level: int, reach) -> int:
        """The level's fill texels within ``reach`` (mesh units) of their seam; their rectangles built
        (:meth:`draw` then finds them without a search)."""
        n = self.count(level, reach)
        if n:
            self._steps[(level, float(reach))] = self._range(level, n)
        return n

    def draw(self, tex, fbo, level: int, reach: float):
        """Fill the level's seam texels of ``tex`` within ``reach`` (mesh units) of their seam (drawn
        through ``fbo``, whose only target ``tex`` is)."""
        reach = float(reach)
        got = self._steps.get((level, reach))
        if got is None:
            self.prepare_step(level, reach)
            got = self._steps.get((level, reach), (0, 0))
        first, count = got
        if count == 0:
            return
        fill, weights = self._levels[level]
        fbo.use()
        tex.use(0)
        fill.use(1)
        weights.use(2)
        self._prog["uReach"].value = reach
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self._vao.render(moderngl.TRIANGLES, vertices=count, first=first)
