"""The interreflection bake (dermis.geometry.interreflection) as textures for the bounce gathers
(tsd's and the shared one). The higher bounces' rays: rg32f, the texture-space (u, v) of each ray's
first hit, (-1, -1) where the ray brings nothing; vertex v's K (SERIES_RAYS) rays are the texels
(x * K + k, y) with (x, y) = (v mod P, v div P), P = vertices per row, so that a row is at most
ROW_TEXELS wide (GL 4.5 guarantees 16384). The one bounce's: all the bake's rays merged per vertex
and texel cell (InterreflectionHits). Built once per product key "interreflection_bake"
(dermis.invalidation: the mesh), texture-space layout and the one bounce's level."""

from __future__ import annotations

import math

import moderngl
import numpy as np

from dermis.geometry.texture_space import texture_space_uvs
from dermis.gl.irradiance_inputs import IrradianceInputs, light_pass
from dermis.invalidation import fingerprint

ROW_TEXELS = 4096
ENTRY_ROW = 4096  # entries per row of the one bounce's merged hits (InterreflectionHits.entries)


def hit_layout(n_vertices: int, rays: int) -> tuple[int, int]:
    """(vertices per row, rows) of the hits texture and of the per-vertex bounce target."""
    per_row = max(1, ROW_TEXELS // max(int(rays), 1))
    return per_row, max(1, -(-int(n_vertices) // per_row))


class InterreflectionHits:
    """The bake on the GPU, one per Renderer (Renderer.interreflection_hits: tsd's bounce and the
    shared one read it); ``get`` rebuilds it when the mesh, its layout or the one bounce's level
    changes. Two forms of the same rays:

    - :attr:`tex`, the higher bounces' rays (rg32f; dermis.geometry.interreflection.SERIES_RAYS, every
      series_step-th of the bake, K of them per vertex as the module's docstring lays out; the
      per-vertex targets share its layout, :attr:`per_row`);
    - :attr:`header` and :attr:`entries`, the one bounce's: all the bake's rays merged per vertex and
      bilinear cell of the level it reads (dermis.geometry.interreflection.merge_hits): header, rg32i
      in the per-vertex layout, (offset, count) into entries, rgb32f (u, v, share), entry e at
      (e mod ENTRY_ROW, e div ENTRY_ROW)."""

    def __init__(self, ctx, placeholder: bool = False):
        self.ctx = ctx
        self.tex = self.header = self.entries = None
        self.key = None
        if placeholder:  # 1x1 stand-ins, replaced by get(): the count of live textures never changes
            self.tex = ctx.texture((1, 1), 2, dtype="f4")
            self.header = ctx.texture((1, 1), 2, dtype="i4")
            self.entries = ctx.texture((1, 1), 3, dtype="f4")
        self.per_row = 1
        self.rays = 0  # the bake's rays per vertex (the one bounce's)
        self.series_rays = 0  # the texels per vertex of tex (the higher bounces')
        self.vertex_count = 0
        self.entry_count = 0
        self.cells = 0  # the texels across the level the one bounce reads (first_order_size)

    def get(self, frame):
        """The hits textures for ``frame``; appends "interreflection_bake" to frame.passes_run when built."""
        from dermis.geometry.interreflection import mesh_hits

        m = frame.scene.mesh
        uv_ts = texture_space_uvs(m)
        cells = first_order_size(frame)
        key = (frame.keys["interreflection_bake"], fingerprint(uv_ts), cells)
        if key != self.key or self.tex is None or self.tex.size == (1, 1):
            with frame.timer("interreflection_bake"):
                hits = mesh_hits(m)
                data, head, ent, k, per_row, rows, n_entries = hit_arrays(hits, uv_ts, m.indices, cells)
                n, rays = hits.triangle.shape
                erows = len(ent) // ENTRY_ROW
                self.release()
                self.tex = self.ctx.texture((per_row * k, rows), 2, dtype="f4")
                self.tex.write(np.ascontiguousarray(data.reshape(rows, per_row * k, 2)).tobytes())
                self.header = self.ctx.texture((per_row, rows), 2, dtype="i4")
                self.header.write(np.ascontiguousarray(head).tobytes())
                self.entries = self.ctx.texture((ENTRY_ROW, erows), 3, dtype="f4")
                self.entries.write(np.ascontiguousarray(ent).tobytes())
                for t in (self.tex, self.header, self.entries):
                    t.filter = (moderngl.NEAREST, moderngl.NEAREST)
                self.per_row, self.rays, self.series_rays, self.vertex_count = per_row, rays, k, n
                self.entry_count, self.cells = n_entries, cells
            self.key = key
            frame.passes_run.append("interreflection_bake")
        return self.tex

    def release(self):
        for t in (self.tex, self.header, self.entries):
            if t is not None:
                t.release()
        self.tex = self.header = self.entries = None
        self.key = None


HIT_ARRAYS_KEEP = 2
"""Merged hits (and hit uvs) kept in memory at once, process-wide: the viewer's two irradiance sizes
(full and reduced) of one mesh; a batch of many meshes does not hold ~50-80 MB per head it rendered."""


def hit_arrays(hits, uv_ts, indices, cells: int):
    """The textures' contents for a bake ``hits`` (dermis.geometry.interreflection.VertexHits) on a
    texture-space layout ``uv_ts`` (per vertex) read at a ``cells``^2 level: (series rays (rows *
    per_row, K, 2) float32, header (rows * per_row, 2) int32, entries (rows * ENTRY_ROW, 3) float32, K,
    per_row, rows, the entries' count), read-only. A function of the bake's and the layout's content
    and ``cells`` alone, remembered by that content (dermis.invalidation.memo_by_content): every
    Renderer of one mesh and irradiance size shares it (the tests' many Renderers), and what does not
    depend on ``cells`` (the hits' uvs, the series rays: :func:`_hit_uvs`) is shared across sizes too
    (the viewer's reduced-size renderer merges only). Benchmarks/RESULTS.md, "Round 17, branch bake17"."""
    from dermis.invalidation import memo_by_content, read_only

    def compute():
        from dermis.geometry.interreflection import merge_hit_uvs

        hit, u, data, k, per_row, rows = _hit_uvs(hits, uv_ts, indices)
        offsets, counts, entries = merge_hit_uvs(hit, u, cells)
        n = len(offsets)
        head = np.zeros((rows * per_row, 2), np.int32)
        head[:n, 0], head[:n, 1] = offsets, counts
        erows = max(1, -(-len(entries) // ENTRY_ROW))
        ent = np.zeros((erows * ENTRY_ROW, 3), np.float32)
        ent[:len(entries)] = entries
        return data, read_only(head), read_only(ent), k, per_row, rows, len(entries)

    return memo_by_content("interreflection_hit_arrays", (hits.triangle, hits.barycentric, uv_ts, indices),
                           int(cells), compute, keep=HIT_ARRAYS_KEEP)


def _hit_uvs(hits, uv_ts, indices):
    """What :func:`hit_arrays` needs at every level: (the (n, K) mask of the rays that hit, their
    texture-space uvs (h, 2) float64: VertexHits.at_hits, the series rays' texture (rows * per_row,
    K_series, 2) float32, K_series, per_row, rows), read-only, remembered by content (~0.5 s of
    interpolation on the head)."""
    from dermis.invalidation import memo_by_content, read_only

    def compute():
        hit, u = hits.at_hits(uv_ts, indices)
        n = hits.triangle.shape[0]
        sub = hits.series_subset().at_vertices(uv_ts, indices)  # (n, K, 2), NaN: nothing
        sub = np.where(np.isfinite(sub), sub, -1.0).astype(np.float32)
        k = sub.shape[1]
        per_row, rows = hit_layout(n, k)
        data = np.full((rows * per_row, k, 2), -1.0, np.float32)
        data[:n] = sub
        return read_only(hit), read_only(u), read_only(data), k, per_row, rows

    return memo_by_content("interreflection_hit_uvs", (hits.triangle, hits.barycentric, uv_ts, indices), None,
                           compute, keep=HIT_ARRAYS_KEEP)


def first_order_size(frame) -> int:
    """The texels across the level the one bounce reads (FIRST_ORDER_FINER_LEVELS finer than
    :func:`bounce_level`'s, at the renderer's irradiance size): the cells its merged hits share."""
    S = int(frame.renderer.irradiance_size)
    level = bounce_level(layout_texels_per_mm(frame.scene, S), S)
    return max(S >> max(level - FIRST_ORDER_FINER_LEVELS, 0), 1)


# ---------------------------------------------------------------------- the gather, shared
BOUNCE_TEXEL_MM = 2.0
"""The higher bounces' gathers read rho T at the level whose texels are about this wide (mm, at the
layout's median stretch): a box as wide as the profile's widest Gaussians (d'Eon's red: sigma 2.7 mm),
so the light read is close to the diffused light that leaves the skin (tsd/bounce_exitant.frag); the
one bounce reads FIRST_ORDER_FINER_LEVELS finer."""


def bounce_level(texels_per_mm: float | None, size: int) -> int:
    """The level (2x2 reductions of a ``size``^2 texture-space layout) whose texels are about
    BOUNCE_TEXEL_MM wide at ``texels_per_mm`` (the layout's median stretch at level 0), and at
    least 16 texels across."""
    lvl = math.floor(math.log2(max(BOUNCE_TEXEL_MM * (texels_per_mm or 1.0), 1.0)))
    return int(max(0, min(lvl, math.log2(max(size, 16) / 16))))


def read_per_vertex(target, n: int) -> np.ndarray:
    """The first ``n`` vertices' rgb of a per-vertex target of the hits' layout (rgba32f, vertex v
    at (v mod P, v div P)), (n, 3)."""
    a = np.frombuffer(target.read(), np.float32).reshape(target.size[1], target.size[0], 4)
    return a.reshape(-1, 4)[:n, :3].copy()


class BounceGather:
    """tsd/bounce_gather.frag on one context: E_b = (1/K) sum_k rho E(y_k) per mesh vertex, from the
    hits (:class:`InterreflectionHits`) and a texture-space rho E (premultiplied by coverage), into
    an rgba32f target of the hits' layout (vertex v at (v mod P, v div P))."""

    def __init__(self, ctx, base: bool = False):
        from dermis.gl.shaders import program

        self.ctx = ctx
        # base: a step of the higher bounces, T_n = E_b + G T_(n-1) (BOUNCE_BASE; BounceSeries) over
        # the series' rays (InterreflectionHits.tex); else the one bounce over the merged hits
        # (BOUNCE_MERGED: InterreflectionHits.header, .entries)
        self.base = bool(base)
        self.prog = program(ctx, "common/fullscreen.vert", "tsd/bounce_gather.frag",
                            {"BOUNCE_BASE": 1} if self.base else {"BOUNCE_MERGED": 1})
        self.vao = ctx.vertex_array(self.prog, [])
        self.target = None
        self.fbo = None
        self._make_target((1, 1))  # re-made at the hits' layout by run()

    def _make_target(self, size):
        self._release_target()
        self.target = self.ctx.texture(size, 4, dtype="f4")
        self.target.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.fbo = self.ctx.framebuffer(color_attachments=[self.target])

    def run(self, hits: InterreflectionHits, exitant, base=None):
        """Gather into :attr:`target` (made at the hits' layout) and return it; ``base`` (per vertex,
        this layout; only with ``base=True`` at construction) is added."""
        from dermis.gl.resources import set_uniform, use_texture
        from dermis.techniques.shared import Unit

        # E_b past the material's units: the series' raster reads the albedo map (Unit.ALBEDO)
        # between two gathers
        base_unit = int(Unit.FIRST_FREE)
        size = (hits.per_row, hits.tex.size[1])
        if self.target is None or self.target.size != size:
            self._make_target(size)
        for name, value in (("uRays", hits.series_rays), ("uVerticesPerRow", hits.per_row),
                            ("uVertexCount", hits.vertex_count), ("uHits", 0), ("uExitant", 1), ("uBase", base_unit),
                            ("uHeader", 0), ("uEntries", base_unit)):
            set_uniform(self.prog, name, int(value))
        use_texture(exitant, 1)
        if self.base:
            use_texture(hits.tex, 0)
            use_texture(base, base_unit)
        else:
            use_texture(hits.header, 0)
            use_texture(hits.entries, base_unit)
        self.fbo.use()
        self.fbo.viewport = (0, 0, *size)
        self.vao.render(moderngl.TRIANGLES, vertices=3)
        return self.target

    def per_vertex(self, n: int) -> np.ndarray:
        """E_b of the last gather per mesh vertex, (n, 3)."""
        return read_per_vertex(self.target, n)

    def _release_target(self):
        for o in (self.fbo, self.target):
            if o is not None:
                o.release()
        self.fbo = self.target = None

    def release(self):
        self._release_target()
        self.vao.release()
        self.prog.release()


# ---------------------------------------------------------------------- the source's levels
class LevelChain:
    """rho E (the one bounce's source) or rho T (a higher order's) from the level it is rasterised at,
    SOURCE_FINER_LEVELS finer than the ~2 mm level (:func:`bounce_level`), 2x2-reduced to it
    (tsd/downsample.frag) for the higher orders' gathers; the shared one bounce reads the raster's level
    itself (FIRST_ORDER_FINER_LEVELS: ``reduce`` of the first level alone runs no pass). The textures
    are made as 1x1 stand-ins and re-made at their sizes on first use (the count of live GPU objects
    never changes; a level-0 gather uses the first alone). Used by :class:`SharedBounce` and
    :class:`BounceSeries`."""

    def __init__(self, ctx):
        from dermis.gl.resources import nearest_sampler
        from dermis.gl.shaders import program

        self.ctx = ctx
        self._down = program(ctx, "common/fullscreen.vert", "tsd/downsample.frag")
        self._down_vao = ctx.vertex_array(self._down, [])
        self._nearest = nearest_sampler(ctx)  # the reduction's texel reads (tsd/downsample.frag)
        self._levels = [self._level_texture(1) for _ in range(SOURCE_FINER_LEVELS + 1)]

    def _level_texture(self, n: int):
        t = self.ctx.texture((n, n), 4, dtype="f4")
        t.filter = (moderngl.LINEAR, moderngl.LINEAR)
        t.repeat_x = t.repeat_y = False
        return t, self.ctx.framebuffer(color_attachments=[t])

    def levels(self, size: int, level: int):
        """[(texture, framebuffer)] from the raster's level to ``level`` of a ``size``^2 layout, made
        at their sizes when they changed."""
        sizes = [max(size >> lvl, 1) for lvl in range(max(level - SOURCE_FINER_LEVELS, 0), level + 1)]
        for i, n in enumerate(sizes):
            if self._levels[i][0].size != (n, n):
                for o in reversed(self._levels[i]):
                    o.release()
                self._levels[i] = self._level_texture(n)
        return self._levels[:len(sizes)]

    def reduce(self, levels):
        """Each level 2x2-reduced into the next; returns the last (the gather's) texture."""
        from dermis.gl.resources import set_uniform, use_texture

        set_uniform(self._down, "uSource", 0)
        for (src, _), (dst, dfbo) in zip(levels, levels[1:]):
            use_texture(src, 0)
            self._nearest.use(0)
            dfbo.use()
            dfbo.viewport = (0, 0, *dst.size)
            self._down_vao.render(moderngl.TRIANGLES, vertices=3)
            self._nearest.clear(0)  # the gather reads the last level bilinearly (tsd/bounce_gather.frag)
        return levels[-1][0]

    def release(self):
        for t, f in self._levels:
            f.release()
            t.release()
        self._levels = []
        self._down_vao.release()
        self._down.release()
        self._nearest.release()


# ---------------------------------------------------------------------- the higher bounces
class BounceSeries:
    """The bounce light's higher orders on one context (dermis.geometry.interreflection, "Higher
    bounces"): from the one bounce E_b per vertex (a :class:`BounceGather`'s target), ``orders`` - 1
    steps T_n = E_b + G T_(n-1), each one raster of rho T_(n-1) in texture space (tsd/bounce_splat.frag
    with BOUNCE_EXITANT: the per-vertex T interpolated over the triangles times the albedo map, the
    same rho as the one bounce's rho E, sampled once per material and layout into a texture of the
    raster's size (BOUNCE_RHO) and read back per order with one texel fetch), SOURCE_FINER_LEVELS finer than the gather's level and
    2x2-reduced to it (tsd/downsample.frag, as the shared one bounce's rho E), then the one bounce's
    gather over the same rays with E_b added (tsd/bounce_gather.frag with BOUNCE_BASE); rasterised at
    the gather's level instead (one texel one albedo sample) the head's higher orders moved by 11% of
    their 99th percentile per vertex (front-key, irradiance 1024: benchmarks/RESULTS.md, "Round 13,
    branch bounce13"), for 4 ms less per order on llvmpipe. T_n is
    written over T_(n-1): no pass reads the texture it writes (the raster reads T_(n-1), the gather
    the raster's reduction and E_b). Used by tsd's bounce and the shared one alike."""

    def __init__(self, ctx):
        from dermis.gl.shaders import program

        self.ctx = ctx
        self._gather = BounceGather(ctx, base=True)
        self._splat = program(ctx, "tsd/uv_space.vert", "tsd/bounce_splat.frag",
                              {"INTERREFLECTION": 1, "BOUNCE_EXITANT": 1})
        # rho at the orders' raster level, drawn once per (material, layout, size) (BOUNCE_RHO) and
        # read back per order with one texel fetch: the albedo map's sample in every order's raster
        # was ~a third of the series on llvmpipe (benchmarks/RESULTS.md, "Round 14, branch perf14c")
        # without INTERREFLECTION: the raster of rho alone reads no per-vertex bounce
        self._rho_prog = program(ctx, "tsd/uv_space.vert", "tsd/bounce_splat.frag", {"BOUNCE_RHO": 1})
        self._rho = None  # made at the raster's size on first use (_draw_rho)
        self._rho_fbo = None
        self._rho_key = None
        self._chain = LevelChain(ctx)  # rho T from the raster's level to the gather's

    def _release_rho(self):
        for o in (self._rho_fbo, self._rho):
            if o is not None:
                o.release()
        self._rho = self._rho_fbo = self._rho_key = None

    def _draw_rho(self, frame, size):
        """rho (albedo_at: tsd/bounce_splat.frag with BOUNCE_RHO) at ``size``, when its key changed:
        the raster the orders' rasters repeat, with the same state (bind_scene, no anisotropy)."""
        from dermis.gl.resources import maps_without_anisotropy
        from dermis.techniques.base import bind_scene

        # "interreflection_inputs": the mesh, its layout, the material (and more: never stale)
        key = (frame.keys["interreflection_inputs"], tuple(size))
        if key == self._rho_key:
            return
        if self._rho is None or self._rho.size != tuple(size):
            self._release_rho()
            self._rho = self.ctx.texture(tuple(size), 4, dtype="f4")
            self._rho.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._rho_fbo = self.ctx.framebuffer(color_attachments=[self._rho])
        bind_scene(frame, self._rho_prog)
        self._rho_fbo.use()
        self._rho_fbo.viewport = (0, 0, *size)
        self._rho_fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        with maps_without_anisotropy(frame.gpu, surfaces=False):
            frame.gpu.vao(self._rho_prog).render(moderngl.TRIANGLES)
        self._rho_key = key

    def run(self, frame, hits: InterreflectionHits, first: BounceGather, level: int, orders: int | None = None):
        """T_orders per vertex (default: the frame's Renderer.bounce_orders, else BOUNCE_ORDERS) from
        ``first`` (the one bounce, gathered at ``level`` of the irradiance size): ``first.target``
        itself when ``orders`` is 1, else this series' target."""
        from dermis.geometry.interreflection import BOUNCE_ORDERS
        from dermis.gl.resources import maps_without_anisotropy, set_uniform, use_texture
        from dermis.techniques.base import bind_scene
        from dermis.techniques.shared import Unit

        if orders is None:
            orders = getattr(frame.renderer, "bounce_orders", None)
        n = int(BOUNCE_ORDERS if orders is None else orders)
        if n <= 1:
            return first.target
        levels = self._chain.levels(int(frame.renderer.irradiance_size), level)
        rho_unit = int(Unit.FIRST_FREE) + 1
        self._draw_rho(frame, levels[0][0].size)
        bind_scene(frame, self._splat)  # the material's uniforms (rho itself from uRho)
        set_uniform(self._splat, "uVerticesPerRow", int(hits.per_row))
        set_uniform(self._splat, "uBounce", int(Unit.FIRST_FREE))
        set_uniform(self._splat, "uRho", rho_unit)
        use_texture(self._rho, rho_unit)
        vao = frame.gpu.vao(self._splat)
        source = first.target
        for _ in range(n - 1):
            tex, fbo = levels[0]
            use_texture(source, Unit.FIRST_FREE)
            fbo.use()
            fbo.viewport = (0, 0, *tex.size)
            fbo.clear(0.0, 0.0, 0.0, 0.0)  # coverage 0 off the layout
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
            with maps_without_anisotropy(frame.gpu, surfaces=False):
                vao.render(moderngl.TRIANGLES)
            source = self._gather.run(hits, self._chain.reduce(levels), base=first.target)
        return source

    @property
    def target(self):
        return self._gather.target

    def release(self):
        self._chain.release()
        self._gather.release()
        self._splat.release()
        self._release_rho()
        self._rho_prog.release()


# ---------------------------------------------------------------------- the shared product
SOURCE_FINER_LEVELS = 1
"""The shared bounce's rho E (and the higher orders' rho T) is rasterised this many levels finer than
the ~2 mm level (:func:`bounce_level`): the one bounce reads it there (FIRST_ORDER_FINER_LEVELS), the
higher orders 2x2-reduced to ~2 mm, each texel a box average of 4^SOURCE_FINER_LEVELS samples.
Chosen by measurement against tsd's bounce on the head (benchmarks/RESULTS.md, "Round 8, branch
bounce8")."""


FIRST_ORDER_FINER_LEVELS = 1
"""The one bounce (the first order: tsd's and the shared one) reads rho E this many levels finer than
:func:`bounce_level`'s ~2 mm (here ~1 mm texels: the shared raster itself, SOURCE_FINER_LEVELS, no
reduction); the higher orders keep the ~2 mm level (their light is a gather of a gather, smooth). On
the head against Cycles' render without subsurface scattering (lambert, 128 rays) the 1 mm read took
FLIP back-ears 0.0237 -> 0.0222, front-key 0.0123 -> 0.0118 for no extra raster (benchmarks/RESULTS.md,
"Round 17, branch bounce17"); the bounce light's own edges (the lit ear's back against the scalp)
are ~1 mm sharp in Cycles."""


class SharedBounce:
    """The one-bounce irradiance E_b per mesh vertex for the techniques without a texture-space
    irradiance of their own (ssss, preintegrated, lambert), one per Renderer, built once per product
    key "interreflection" (dermis.invalidation: the lights, environment, material, mesh) and shared by
    all of them: a camera-only frame reads it with one texel fetch per vertex (common/mesh.vert with
    DERMIS_INTERREFLECTION).

    rho E is tsd's own irradiance pass (tsd/irradiance.frag: lights, soft shadows, occluded ambient,
    energy conservation, the directional albedo at entry) with mix = 1, so that it writes
    E albedo^1 = rho E, the light leaving the skin times pi (tsd's bounce_exitant.frag reads the same
    from I_0 albedo^(1 - mix)); rasterised small (SOURCE_FINER_LEVELS above the ~2 mm level,
    :func:`bounce_level`: ~1 mm) and gathered there over all the baked rays, merged per texel cell
    (:class:`BounceGather`, InterreflectionHits). It is drawn in two passes (tsd/irradiance.frag, SKIN_BOUNCE_INPUTS and
    SKIN_BOUNCE_FROM_INPUTS): the mesh raster of what depends on no light (the maps, normals, the
    directional albedo's c, albedo^mix, the occluded ambient; 5 rgba32f targets) once per product key
    "interreflection_inputs", and per lighting change a full-screen pass over those texels adding
    the lights: the same floats as one raster, ~40% cheaper per lighting change on llvmpipe
    (benchmarks/RESULTS.md, "Round 11, branch perf11")."""

    def __init__(self, ctx, hits: InterreflectionHits):
        # everything is made here, when the first technique that reads the bounce is built (as the
        # techniques compile their programs up front: the viewer switches techniques mid-drag), the
        # textures as 1x1 stand-ins re-made at their sizes on first use
        from dermis.techniques.shared import LightCountPrograms

        self.ctx = ctx
        self.hits = hits  # the Renderer's (Renderer.interreflection_hits), released by it
        self._gather = BounceGather(ctx)
        self._series = BounceSeries(ctx)
        self._out = self._gather.target  # the per-vertex bounce the techniques read (every order)
        # per light count, its lights unrolled as tsd's own irradiance pass (shared.LightCountPrograms),
        # and per light signature as tsd's light pass (the kinds and shadow kernels as constants: the
        # same floats, less arithmetic on llvmpipe; benchmarks/results/round-24.md, irr24 and sig24)
        self.programs = LightCountPrograms(ctx, "common/fullscreen.vert", "tsd/irradiance.frag",
                                           {"SKIN_BOUNCE_FROM_INPUTS": 1}, signature=True)
        self.inputs = IrradianceInputs(ctx)  # rho E's light-independent inputs (dermis.gl.irradiance_inputs)
        self._vaos = {}  # light-pass program -> its attribute-less vertex array
        self._chain = LevelChain(ctx)  # rho E from the raster's level to the gather's
        self.key = None
        self.level = None  # the gather's level (of the irradiance size)
        self._exitant_key = None  # the product key rho E was last drawn for (:meth:`exitant`)
        self._exitant_levels = None  # (irradiance size, bounce level) it was drawn at

    @property
    def texture(self):
        return self._out

    @property
    def exitant_key(self):
        """The product key rho E (:meth:`exitant`) was last drawn for (None: never)."""
        return self._exitant_key

    def exitant(self, frame):
        """rho E, the light leaving the skin times pi, in texture space at the one bounce's ~1 mm level
        (premultiplied by coverage, rgba32f: tsd/irradiance.frag with mix = 1), redrawn when the product
        key "interreflection" changed (the lights, environment, material, mesh, irradiance size). What
        the bounce gathers, and what ssss and preintegrated gather the baked subsurface transfer from
        (dermis.gl.subsurface_transfer.SubsurfaceTransfer.screen_grid): drawn whether or not the scene has the
        bounce. Appends "interreflection_exitant" to frame.passes_run when drawn."""
        key = frame.keys["interreflection"]
        if key == self._exitant_key:
            return self._chain.levels(*self._exitant_levels)[0][0]
        from dermis.techniques.base import bind_scene
        from dermis.techniques.shared import Unit

        S = int(frame.renderer.irradiance_size)
        level = bounce_level(layout_texels_per_mm(frame.scene, S), S)
        tex, fbo = self._chain.levels(S, level)[0]
        # mix = 1: E albedo^1 = rho E
        self.inputs.draw(frame, tex.size, mix=1.0, pass_name="interreflection_inputs")
        with frame.timer("interreflection"):
            prog = self.programs(frame.lights.count, frame.lights.lights)
            bind_scene(frame, prog)
            self.inputs.bind(prog, Unit.FIRST_FREE)
            light_pass(self.ctx, self._vaos, prog, fbo, tex.size)
        self._exitant_key, self._exitant_levels = key, (S, level)
        frame.passes_run.append("interreflection_exitant")
        return tex

    def get(self, frame):
        """The per-vertex E_b texture for ``frame`` (rebuilt when the product key changed); appends
        "interreflection" to frame.passes_run when it ran."""
        self.hits.get(frame)  # the bake times itself, and may be rebuilt alone (a new layout)
        key = (frame.keys["interreflection"], self.hits.key)
        if key == self.key:
            return self._out
        self.exitant(frame)
        S, level = self._exitant_levels
        self.level = level
        levels = self._chain.levels(S, level)
        with frame.timer("interreflection"):
            # the one bounce from the level FIRST_ORDER_FINER_LEVELS finer than the ~2 mm one
            first = max(level - FIRST_ORDER_FINER_LEVELS, 0) - max(level - SOURCE_FINER_LEVELS, 0)
            self._gather.run(self.hits, self._chain.reduce(levels[:max(first, 0) + 1]))
            out = self._series.run(frame, self.hits, self._gather, level)  # + the higher bounces
        self._out = out
        self.key = key
        frame.passes_run.append("interreflection")
        return out

    def per_vertex(self) -> np.ndarray:
        """The bounce irradiance of the last build per mesh vertex, (n, 3): T, every order
        (:class:`BounceSeries`)."""
        return read_per_vertex(self._out, self.hits.vertex_count)

    def first_per_vertex(self) -> np.ndarray:
        """E_b, the one bounce, of the last build per mesh vertex, (n, 3)."""
        return self._gather.per_vertex(self.hits.vertex_count)

    def release(self):
        self._chain.release()
        self.inputs.release()
        for v in self._vaos.values():
            v.release()
        self._vaos = {}
        self._gather.release()
        self._series.release()
        self._out = None
        self.programs.release()
        self.key = None
        self._exitant_key = None


def layout_texels_per_mm(scene, size: int) -> float:
    """The texture-space layout's median stretch at ``size``^2 (texels per mm,
    dermis.geometry.interreflection.layout_median_stretch: tsd's stretch map's median without the
    raster), remembered per content."""
    from dermis.geometry.interreflection import layout_median_stretch
    from dermis.invalidation import memo_by_content, read_only

    m = scene.mesh
    uv = texture_space_uvs(m)
    return memo_by_content("layout_median_stretch", (m.positions, uv, m.indices), (float(scene.mm_per_unit), int(size)),
                           lambda: layout_median_stretch(m.positions, uv, m.indices, scene.mm_per_unit, size))
