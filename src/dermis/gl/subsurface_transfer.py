"""The baked subsurface transfer (dermis.subsurface_transfer) at run time, in tsd's texture space:
the same-side transport that an ear's thin, curled geometry adds to (or takes from) the flat profile
tsd's blur chain applies, gathered from the blurred irradiance map and added to the translucency
target. Passes, only where a bake exists (tsd/transfer_gather.frag, tsd/transfer_view_box.frag,
tsd/transfer_add.frag), each drawn as tiles near the bake points only (tsd/transfer_tiles.vert):

  gather: at each texel of the bake's grid that holds a bake point (tsd/transfer_index.vert's map, drawn
          once per bake: one GL point per bake point, the last drawn where two share a texel):
          sum_k w_k I(uv_k); the grid's other texels stay the 0 they were cleared to at upload
  view box: the view grids' 2 x 2 box sums (:meth:`SubsurfaceTransfer.view_box`)
  add:    the grid read (trilinear: its mipmaps where the target is coarser) at each texel of the
          translucency target that can receive transfer (:func:`add_tiles`), additive blending

ssss and preintegrated (round 21, ears21) read the same grid at each fragment's texture-space uv
(:meth:`SubsurfaceTransfer.screen_grid`, common/subsurface_transfer.glsl: the add pass's tent), gathered
from the shared rho E (dermis.gl.interreflection.SharedBounce.exitant) instead of tsd's I_3.

A scene without a matching bake (dermis.subsurface_transfer.store.find) draws neither: its image is
the one tsd gave before. The bake is looked up once per PRODUCTS key "subsurface_transfer"
(dermis.invalidation: mesh, scale, profile, material) and kept on the GPU until it changes.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

TAP_VARIANCE_MM2 = 0.15
"""The taps read the first blurred irradiance I_k whose variance is at least this (d'Eon's profile:
I_3, 0.187 mm^2, sigma 0.43 mm): a tap stands for its cluster of vertices (the bake's graph is the
mesh subdivided twice, vertices ~0.3-1 mm apart on the ear) and the point's own tap for the exits
within 1 mm, so it reads the irradiance averaged over about that footprint, not a point of the raw
map (shadow edges, pores)."""
POINTS_PER_ROW = 256
BOX_TILE = 8
"""Texels per side of the tiles the gather, :meth:`SubsurfaceTransfer.view_box` and the add draw
(tsd/transfer_tiles.vert)."""
VIEW_IMAGE = 1
"""The first of the three image units common/subsurface_transfer.glsl's view term reads (the view grids' 2 x 2
box sums of red, green, blue: :meth:`SubsurfaceTransfer.view_box`; unit 0 is the mesh's triangle frames)."""


def source_index(variances_mm2) -> int:
    """Which blurred irradiance I_(k+1) the taps read (:data:`TAP_VARIANCE_MM2`)."""
    v = np.asarray(variances_mm2, np.float64)
    big = np.nonzero(v >= TAP_VARIANCE_MM2)[0]
    return int(big[0]) if len(big) else len(v) - 1


def add_tiles(texels, grid_size, level: int, target_size, tile: int = BOX_TILE) -> np.ndarray:
    """The tiles (``tile`` texels a side; (m, 2) float32 indices per axis, unique) of a target of
    ``target_size`` whose texels can read a non-zero grid texel through the add's tent
    (common/subsurface_transfer.glsl at ``level``), where the grid's level 0 is non-zero only at
    ``texels`` ((m, 2) integer (x, y): the texels GL rasterised the bake points to, read back from the
    point map, :attr:`SubsurfaceTransfer.held`; not floor(uv * grid), which llvmpipe's 1/256 px snap of
    a point's position can put in the neighbouring texel for a uv on or near a texel edge) and level L at
    their texels >> L (its box mipmap). The tent's four bilinear reads at the target texel's centre
    u +- 0.5 level texel reach the level's texels j with |(j + 0.5) / g - u| < 1.5 / g (g: the level's
    texels per axis); taken with 2 / g, so target texel x is drawn where
    floor((i - 1.5) T / g - 0.5) <= x <= ceil((i + 2.5) T / g - 0.5) for a non-zero texel i (T the target's
    texels). The other texels add 0: drawn or not, the target keeps its value."""
    grid = np.asarray(grid_size, np.int64)
    g = np.maximum(grid >> int(level), 1)
    T = np.asarray(target_size, np.float64)
    held = np.asarray(texels, np.int64).reshape(-1, 2)
    i = np.unique(np.clip(held, 0, grid - 1) >> int(level), axis=0)
    i = np.minimum(i, g - 1).astype(np.float64)
    lo = np.floor((i - 1.5) * T / g - 0.5).astype(np.int64)
    hi = np.ceil((i + 2.5) * T / g - 0.5).astype(np.int64)
    n_tiles = -(-np.asarray(target_size, np.int64) // tile)
    t0 = np.clip(lo // tile, 0, n_tiles - 1)
    t1 = np.clip(hi // tile, 0, n_tiles - 1)
    span = int((t1 - t0).max()) + 1 if len(i) else 0
    out = [np.minimum(t0 + (dx, dy), t1) for dx in range(span) for dy in range(span)]
    if not out:
        return np.zeros((0, 2), np.float32)
    return np.unique(np.concatenate(out), axis=0).astype(np.float32)


def tile_runs(tiles) -> np.ndarray:
    """``tiles`` ((m, 2) tile indices per axis, unique) as runs along x, (r, 3) float32 (first tile's x, y,
    tiles in the run): what tsd/transfer_tiles.vert draws, one quad per run. The same texels as a quad per
    tile, in fewer triangles: on the head 429 tiles are 88 runs, and the gather's draw 4.7 -> 3.9 CPU ms on
    llvmpipe (its per-triangle setup, round 24)."""
    t = np.asarray(tiles, np.int64).reshape(-1, 2)
    if not len(t):
        return np.zeros((0, 3), np.float32)
    t = np.unique(t, axis=0)
    t = t[np.lexsort((t[:, 0], t[:, 1]))]  # by y, then x
    start = np.r_[True, (np.diff(t[:, 1]) != 0) | (np.diff(t[:, 0]) != 1)]
    first = np.nonzero(start)[0]
    length = np.diff(np.r_[first, len(t)])
    return np.c_[t[first], length].astype(np.float32)


def tap_layout(n_points: int, taps: int) -> tuple[int, int]:
    """(points per row, rows) of the tap textures."""
    return POINTS_PER_ROW, max(1, -(-int(n_points) // POINTS_PER_ROW))


def transfer_numpy(bake, irradiance_premultiplied: np.ndarray, view: bool = False) -> np.ndarray:
    """The gather's numpy twin, (n, 3): sum_k w_k I(uv_k) per bake point with I (h, w, 4) row 0 =
    bottom (v = 0, GL's order), premultiplied, sampled bilinearly at the taps' uv (GL's rule: texel
    centres at (i + 0.5) / w, clamped at the edges), taps with coverage < 1/64 left out. ``view``: the
    view grids' sums instead, (n, 3, 4): per channel sum_k (G_x, G_y, G_z, c)_k I(uv_k)."""
    h, w = irradiance_premultiplied.shape[:2]
    uv = bake.tap_uv.reshape(-1, 2).astype(np.float64)
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    I = np.asarray(irradiance_premultiplied, np.float64)
    at = lambda yy, xx: I[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)]
    c = (at(y0, x0) * ((1 - fx) * (1 - fy))[:, None] + at(y0, x0 + 1) * (fx * (1 - fy))[:, None]
         + at(y0 + 1, x0) * ((1 - fx) * fy)[:, None] + at(y0 + 1, x0 + 1) * (fx * fy)[:, None])
    ok = c[:, 3] >= 1.0 / 64.0
    col = np.where(ok[:, None], c[:, :3] / np.where(ok, c[:, 3], 1.0)[:, None], 0.0)
    wgt = bake.tap_weight.reshape(-1, 3).astype(np.float64)
    if view:
        tv = np.zeros(bake.tap_weight.shape + (4,)) if bake.tap_view is None else np.asarray(bake.tap_view, np.float64)
        return (tv.reshape(-1, 3, 4) * col[:, :, None]).reshape(tv.shape).sum(1)
    return (wgt * col).reshape(bake.tap_weight.shape).sum(1)


class SubsurfaceTransfer:
    """The bake on the GPU and its two passes, one per tsd technique."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.key = None
        self.bake = None
        self._gpu = []  # textures, buffer, vertex arrays, framebuffer of the current bake
        self._progs = None
        self._gathered = None  # what the grid holds (:meth:`screen_grid`): (bake key, source key, mipmaps)
        # what a screen pass's uTransfer samples where the scene has no bake (never read: uTransferLevel < 0)
        self.placeholder = ctx.texture((1, 1), 4, dtype="f4")
        self.view_grids = []  # the view term's grids (red, green, blue) of the current bake
        # their 2 x 2 box sums at the level the readers read (view_box): (textures, framebuffer, level, tiles'
        # vertex array, tiles' buffer, run count: tile_runs)
        self._box = None
        self._box_prog = None
        self.held = np.zeros((0, 2), np.int64)  # the grid's non-zero texels (x, y) of the current bake (_upload)
        self._add = None  # the add's tiles: ((target size, level), vertex array, buffer, run count: tile_runs)
        self.index = 1.4

    def _programs(self):
        if self._progs is None:
            from dermis.gl.shaders import program

            gather = program(self.ctx, "tsd/transfer_tiles.vert", "tsd/transfer_gather.frag")
            # drawn over the tiles that can receive transfer (add_tiles), as the view box's
            add = program(self.ctx, "tsd/transfer_tiles.vert", "tsd/transfer_add.frag")
            index = program(self.ctx, "tsd/transfer_index.vert", "tsd/transfer_index.frag")
            self._progs = (gather, add, index)
        return self._progs

    def _tile_draw(self, prog, tiles):
        """``prog`` (vertex shader tsd/transfer_tiles.vert) drawn over ``tiles`` ((m, 2) tile indices, repeats
        allowed): (vertex array, its buffer, run count), one instanced quad per :func:`tile_runs` run; a count
        of 0 draws nothing (the buffer then holds one unused run: GL buffers cannot be empty)."""
        runs = tile_runs(tiles)
        buf = self.ctx.buffer(np.ascontiguousarray(runs).tobytes() or np.zeros(3, np.float32).tobytes())
        return self.ctx.vertex_array(prog, [(buf, "3f/i", "in_tile")]), buf, len(runs)

    def _release_gpu(self):
        for o in self._gpu:
            o.release()
        self._gpu = []
        self.held = np.zeros((0, 2), np.int64)
        self._release_box()
        self._release_add()

    def _release_add(self):
        if self._add is not None:
            _, vao, buf, _ = self._add
            vao.release()
            buf.release()
            self._add = None

    def _release_box(self):
        if self._box is not None:
            texs, fbo, _, vao, buf, _ = self._box
            for o in (vao, buf, fbo, *texs):
                o.release()
            self._box = None

    def lookup(self, frame):
        """The bake for ``frame``'s scene (or None), looked up once per its product key."""
        key = frame.keys["subsurface_transfer"]
        if key != self.key:
            from dermis.subsurface_transfer.store import find

            self._release_gpu()
            self.bake = find(frame.scene)
            if self.bake is not None and not len(self.bake.point_uv):
                self.bake = None  # a bake of no points transfers nothing: the image is the one without a bake
            self.key = key
            if self.bake is not None:
                self._upload(self.bake)
        return self.bake

    def _upload(self, bake):
        n, k = bake.tap_uv.shape[:2]
        per_row, rows = tap_layout(n, k)
        uv = np.zeros((rows * per_row, k, 4), np.float32)
        uv[:n, :, :2] = bake.tap_uv
        wt = np.zeros((rows * per_row, k, 4), np.float32)
        wt[:n, :, :3] = bake.tap_weight
        views = []
        for c in range(3):  # the view term's coefficients per channel (0 for a bake without one)
            v = np.zeros((rows * per_row, k, 4), np.float32)
            if bake.tap_view is not None:
                v[:n] = bake.tap_view[:, :, c]
            views.append(v)
        texs = []
        for data in (uv, wt, *views):
            t = self.ctx.texture((per_row * k, rows), 4, dtype="f4")
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.write(np.ascontiguousarray(data.reshape(rows, per_row * k, 4)).tobytes())
            texs.append(t)
        grid = int(bake.meta.get("grid", 512))
        grids = []
        for _ in range(4):  # the cosine views' T_geo, then the view term's per channel (red, green, blue)
            target = self.ctx.texture((grid, grid), 4, dtype="f4")
            # mipmapped: a translucency target coarser than the grid (a small irradiance size) reads the
            # grid's average over its texel, not every n-th bake point
            target.build_mipmaps()
            target.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            target.repeat_x = target.repeat_y = False
            grids.append(target)
        target = grids[0]
        fbo = self.ctx.framebuffer(color_attachments=grids)
        # cleared once here, not per gather: every gather writes the same texels (the bake points' own, fixed by
        # point_uv; where two share a texel the later point's, in the same draw order) and no other, so the rest
        # keep this 0 (the mipmap rebuilds write only levels >= 1). On llvmpipe the per-gather clear of the four
        # 512^2 rgba32f grids was ~2.5 of the pass's ~18 CPU ms (round 24, xfer24)
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        gather, _, index = self._programs()
        # the bake point at each texel of the grid (-1: none), drawn once: one GL point per bake point, the
        # last drawn where two share a texel (tsd/transfer_index.vert); until round 23 the gather drew these
        # points every frame
        point_map = self.ctx.texture((grid, grid), 1, np.full(grid * grid, -1, np.int32).tobytes(), dtype="i4")
        point_map.filter = (moderngl.NEAREST, moderngl.NEAREST)
        map_fbo = self.ctx.framebuffer(color_attachments=[point_map])
        if n:  # a bake of no points (ctx.buffer refuses 0 bytes) holds no texel: every pass draws no tile
            buf = self.ctx.buffer(np.ascontiguousarray(bake.point_uv, np.float32).tobytes())
            points = self.ctx.vertex_array(index, [(buf, "2f", "in_uv")])
            map_fbo.use()
            map_fbo.viewport = (0, 0, grid, grid)
            self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
            points.render(moderngl.POINTS, vertices=n)
            points.release()
            buf.release()
        map_fbo.release()
        # the grid's non-zero texels, (m, 2) int (x, y): where GL rasterised the points, which is not always
        # floor(uv * grid) (llvmpipe snaps a point's position to 1/256 px: a uv on or within that of a texel edge
        # can land in the neighbouring texel); the gather's, the view box's and the add's tiles all derive from it
        held = np.argwhere(np.frombuffer(point_map.read(), np.int32).reshape(grid, grid) >= 0)[:, ::-1]
        self.held = held
        # the gather's tiles: those holding a point's texel (on the head 429 of 64^2, 19358 points in 27456 texels), in 88 runs
        vao, tile_buf, runs = self._tile_draw(gather, held // BOX_TILE)
        self._gpu = [*texs, fbo, *grids, point_map, vao, tile_buf]
        self._tap_uv, self._tap_weight, self.grid_texture, self._fbo, self._vao = texs[0], texs[1], target, fbo, vao
        self._point_map, self._gather_tiles = point_map, runs
        self._tap_view = texs[2:]
        self.view_grids = grids[1:]
        # uTransferIndex < 0: a bake without the view term (the cosine grid alone, as before round 22)
        self.index = float(bake.meta.get("index", 1.4)) if bake.tap_view is not None else -1.0
        self._layout = (per_row, k, n)

    def read_level(self, target_size) -> int:
        """The grid's level that common/subsurface_transfer.glsl reads for a target of ``target_size``:
        the one whose texels are at least the target's, ceil(log2(max(grid / target)) - 1e-4), >= 0."""
        g = self.grid_texture.size
        r = max(g[0] / max(int(target_size[0]), 1), g[1] / max(int(target_size[1]), 1))
        return max(0, math.ceil(math.log2(r) - 1e-4))

    def reads_mipmaps(self, target_size) -> bool:
        """Whether a target of ``target_size`` reads the grid above level 0 (:meth:`read_level`): only
        then must a gather rebuild the grid's mipmaps."""
        return self.read_level(target_size) > 0

    def gather(self, irradiance, mipmaps: bool = True) -> None:
        """T_geo per bake point into :attr:`grid_texture` from ``irradiance`` (premultiplied);
        ``mipmaps``: rebuild the grid's mipmaps (False where only level 0 is read: :meth:`reads_mipmaps`;
        on llvmpipe the rebuild of the 512^2 rgba32f grid was ~1.6 ms of the pass's ~12). Drawn over the
        tiles holding a bake point's texel (tsd/transfer_gather.frag); the grids' other texels keep the 0
        of the upload's clear."""
        from dermis.gl.resources import set_uniform, use_texture

        gather, _, _ = self._programs()
        per_row, k, n = self._layout
        for name, value in (("uTapUv", 0), ("uTapWeight", 1), ("uIrradiance", 2), ("uTapView0", 3), ("uTapView1", 4),
                            ("uTapView2", 5), ("uPoint", 6), ("uTaps", k), ("uPointsPerRow", per_row)):
            set_uniform(gather, name, int(value))
        set_uniform(gather, "uBoxSize", tuple(float(s) for s in self.grid_texture.size))
        set_uniform(gather, "uTileTexels", float(BOX_TILE))
        use_texture(self._point_map, 6)
        use_texture(self._tap_uv, 0)
        use_texture(self._tap_weight, 1)
        use_texture(irradiance, 2)
        for u, t in enumerate(self._tap_view):
            use_texture(t, 3 + u)
        self._fbo.use()
        self._fbo.viewport = (0, 0, *self.grid_texture.size)  # no clear: the texels off the points stay 0 (_upload)
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        if self._gather_tiles:
            self._vao.render(moderngl.TRIANGLES, vertices=6, instances=self._gather_tiles)
        if mipmaps:
            self.grid_texture.build_mipmaps()
            for t in self.view_grids:
                t.build_mipmaps()

    def add(self, frame, target_fbo, target_size, irradiance) -> bool:
        """Gather and add T_geo into ``target_fbo`` (tsd's translucency target); False (nothing drawn)
        where the scene has no bake."""
        if self.lookup(frame) is None:
            return False
        from dermis.gl.resources import set_uniform, use_texture

        self.gather(irradiance, mipmaps=self.reads_mipmaps(target_size))
        self.view_box(self.read_level(target_size))
        self._gathered = None
        _, add, _ = self._programs()
        level = self.read_level(target_size)
        size = tuple(int(s) for s in target_size)
        if self._add is None or self._add[0] != (size, level):
            # the target's texels that can receive transfer, in tiles (the rest add 0): on the head ~15 % of
            # the 512^2 translucency target; the full-screen add was ~6 of the pass's ~18 CPU ms on llvmpipe
            # (round 24, xfer24)
            self._release_add()
            self._add = ((size, level), *self._tile_draw(add, add_tiles(self.held, self.grid_texture.size, level, size)))
        _, vao, _, count = self._add
        set_uniform(add, "uTransfer", 0)
        set_uniform(add, "uTransferLevel", float(level))
        set_uniform(add, "uTargetSize", tuple(float(s) for s in size))
        set_uniform(add, "uBoxSize", tuple(float(s) for s in size))
        set_uniform(add, "uTileTexels", float(BOX_TILE))
        use_texture(self.grid_texture, 0)
        target_fbo.use()
        target_fbo.viewport = (0, 0, *size)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        if count:
            vao.render(moderngl.TRIANGLES, vertices=6, instances=count)
        self.ctx.disable(moderngl.BLEND)
        return True

    def screen_grid(self, frame, target_size):
        """(grid texture, level) for a screen pass that reads T_geo at each fragment's texture-space uv
        (common/subsurface_transfer.glsl: ssss's final pass, preintegrated), or None where the scene has
        no bake. Gathered from the shared rho E (dermis.gl.interreflection.SharedBounce.exitant: the
        light leaving the skin times pi at ~1 mm, so T_geo here is what tsd's T_geo(I_3) albedo^(1-mix)
        is where the albedo is uniform over the taps' millimetres) only when that or the bake changed:
        a camera-only frame gathers nothing. ``target_size``: the texture-space target whose level is
        read (tsd's translucency target at the same irradiance size, so that all techniques read the
        same level)."""
        if self.lookup(frame) is None:
            return None
        bounce = frame.renderer.interreflection
        source = bounce.exitant(frame)  # times itself: outside this timer (a GPU's timer queries do not nest)
        mipmaps = self.reads_mipmaps(target_size)
        key = (self.key, bounce.exitant_key, mipmaps)
        if key != self._gathered:
            with frame.timer("subsurface_transfer"):
                self.gather(source, mipmaps=mipmaps)
                self.view_box(self.read_level(target_size))
            self._gathered = key
            frame.passes_run.append("subsurface_transfer")
        return self.grid_texture, self.read_level(target_size)

    def view_box(self, level: int) -> None:
        """The view grids' 2 x 2 box sums at ``level`` (tsd/transfer_view_box.frag), which the readers'
        view term reads (:meth:`bind_view`, common/subsurface_transfer.glsl: its 3 x 3 tent as a bilinear
        blend of 2 x 2 of them, 12 image loads instead of 27); after every gather, none for a bake
        without the view term (uTransferIndex < 0: never read). Drawn only over the tiles
        (:data:`BOX_TILE`) that can hold a non-zero sum (tsd/transfer_tiles.vert): the whole 513^2
        targets took ~8 ms of llvmpipe's CPU per gather, the head's ~12 % of them ~1/8 of that."""
        from dermis.gl.resources import set_uniform, use_texture
        from dermis.gl.shaders import program

        if self.index < 0.0:
            return
        level = int(level)
        if self._box_prog is None:
            self._box_prog = program(self.ctx, "tsd/transfer_tiles.vert", "tsd/transfer_view_box.frag")
        prog = self._box_prog
        g = self.grid_texture.size
        size = tuple(max(int(s) >> level, 1) + 1 for s in g)  # one texel wider per axis
        if self._box is None or self._box[2] != level or self._box[0][0].size != size:
            self._release_box()
            texs = []
            for _ in range(3):
                t = self.ctx.texture(size, 4, dtype="f4")
                t.filter = (moderngl.NEAREST, moderngl.NEAREST)
                texs.append(t)
            fbo = self.ctx.framebuffer(color_attachments=texs)
            fbo.clear(0.0, 0.0, 0.0, 0.0)  # what every texel outside the tiles keeps
            # the level's non-zero texels (the rasterised points' texels >> level: self.held) and the box
            # texels whose 2 x 2 holds one (t and t + 1 per axis: box texel k sums the level's k - 1 and k)
            texel = np.asarray(self.held, np.int64).reshape(-1, 2) >> level
            near = np.concatenate([texel + (dx, dy) for dx in range(2) for dy in range(2)])
            near = np.clip(near, 0, np.asarray(size) - 1)
            self._box = (texs, fbo, level, *self._tile_draw(prog, near // BOX_TILE))
        for u, (name, t) in enumerate(zip(("uViewR", "uViewG", "uViewB"), self.view_grids)):
            set_uniform(prog, name, u)
            use_texture(t, u)
        set_uniform(prog, "uLevel", level)
        set_uniform(prog, "uBoxSize", tuple(float(s) for s in size))
        set_uniform(prog, "uTileTexels", float(BOX_TILE))
        texs, fbo, _, vao, _, count = self._box
        fbo.use()
        fbo.viewport = (0, 0, *size)
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        if count:
            vao.render(moderngl.TRIANGLES, vertices=6, instances=count)

    def bind_view(self, prog, level) -> None:
        """The view term's images for a pass that reads common/subsurface_transfer.glsl's
        subsurface_transfer_view (``level``: the grids' level, uTransferLevel, whose box sums the last
        gather made (:meth:`view_box`); < 0, no bake or none with the view term: the placeholders, never
        read) and its uTransferIndex."""
        from dermis.gl.resources import set_uniform

        if prog.get("uTransferViewR", None) is None:
            return
        live = self.bake is not None and level is not None and level >= 0
        if not live and self.placeholder is None:  # released, then drawn again without a bake
            self.placeholder = self.ctx.texture((1, 1), 4, dtype="f4")
        boxes = [self.placeholder] * 3
        if live and self.index >= 0.0:
            if self._box is None or self._box[2] != int(level):
                raise RuntimeError(f"the view term's box sums are of level {self._box and self._box[2]}, not {level}")
            boxes = self._box[0]
        for u, t in enumerate(boxes):
            t.bind_to_image(VIEW_IMAGE + u, read=True, write=False, level=0)
        set_uniform(prog, "uTransferIndex", float(self.index if live else 1.4))
        from dermis.subsurface_transfer.bake import view_mean_constants

        set_uniform(prog, "uTransferViewMean", view_mean_constants(self.index if live and self.index > 0 else 1.4))

    def per_point(self, view: bool = False) -> np.ndarray:
        """T_geo of the last gather at each bake point, (n, 3) (read back from the grid); ``view``: the
        view grids' (n, 3, 4) (per channel (G_x, G_y, G_z, c) . I)."""
        uv = np.asarray(self.bake.point_uv, np.float64)
        out = []
        for t in (self.view_grids if view else [self.grid_texture]):
            a = np.frombuffer(t.read(), np.float32).reshape(t.size[1], t.size[0], 4)
            x = np.clip((uv[:, 0] * t.size[0]).astype(int), 0, t.size[0] - 1)
            y = np.clip((uv[:, 1] * t.size[1]).astype(int), 0, t.size[1] - 1)
            out.append(a[y, x].copy())
        return np.stack(out, 1) if view else out[0][:, :3]

    def release(self):
        self._release_gpu()
        self._gathered = None
        if self._box_prog is not None:
            self._box_prog.release()
            self._box_prog = None
        if self.placeholder is not None:
            self.placeholder.release()
            self.placeholder = None
        if self._progs is not None:
            for o in self._progs[::-1]:
                o.release()
        self._progs = None
        self.key = None
        self.bake = None
