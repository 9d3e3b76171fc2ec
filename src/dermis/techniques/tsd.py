"""Texture-space diffusion (``tsd``): d'Eon, Luebke & Enderton 2007 / GPU Gems 3 chapter 14.

What it approximates: subsurface scattering in skin as a convolution of the irradiance over the
surface with a radial diffusion profile R(r), represented as a sum of Gaussians sum_k w_k G(v_k, r)
(variances in mm^2, RGB weights; dermis.profiles). The convolution is done in the mesh's UV layout:

  shadow atlas (depth only)                (shared, gl/shadows.py)
  stretch map S_0 (texels per mm)           once per mesh / scale / resolution
  irradiance I_0 = E * albedo^mix           E from all lights with soft shadows, ambient, energy
                                             conservation (1 - rho_s a(N.L, m)/pi); what depends on no
                                             light rasterised once per content, the lights added by one
                                             full-screen pass (dermis.gl.irradiance_inputs, SPLIT_IRRADIANCE)
  one diffuse bounce between skin surfaces (scene.interreflection): E_b = (1/K) sum_k rho E(y_k) over K
                 cosine-weighted rays per vertex (baked once per mesh, geometry/interreflection.py), rho E
                 read from a ~1 mm level of I_0 albedo^(1-mix) (K = 512, merged per texel cell); with
                 its higher orders (BounceSeries, dermis.geometry.interreflection.BOUNCE_ORDERS = 4, as
                 Cycles through the bridge) T = E_b + B E_b + B^2 E_b + B^3 E_b (B: one more diffuse
                 reflection off the skin over 128 of the rays at ~2 mm, geometry/interreflection.py's
                 G); T albedo^mix added to I_0
  dilate I_0 into the UV gutters
  for k = 1..K:  I_k = I_(k-1) * G(v_k - v_(k-1)) as a U then a V pass (chained: G(a)*G(b) = G(a+b)),
                 tap spacing from S_k, the stretch blurred by the same chain; wide Gaussians run at
                 half or quarter resolution (they hold no fine detail); where I_1 and I_2 are
                 sub-texel, both come from one 3x3 pass (tsd/blur_narrow.frag)
  translucency T through thin parts: sum over wide k of w_k exp(-d^2 / 2 v_k) I_k(far face), d the
                 tissue's thickness behind the texel along -N (ray cast once per mesh, geometry/thickness.py);
                 + where the mesh has a baked subsurface transfer (dermis.subsurface_transfer: the same-side
                 transport a thin, curled sheet adds to the flat profile), its taps gathered from I_3 and
                 added to T (gl/subsurface_transfer.py; with translucency on)
  final (screen space): (sum_k w_k I_k + T) * albedo^(1-mix)/pi * (1 - rho_s a(N.V, m)/pi) + specular,
                 I_k and T read at a UV on the fragment's own triangle (tsd/triangle_uv.glsl: an MSAA edge
                 sample of an edge-on triangle is shaded at the pixel centre, off the triangle)

Everything before the final pass is view-independent and cached on the renderer's lighting key:
a camera move re-runs only the final pass (``frame.passes_run`` says what ran).
Inputs and units: the scene's mm_per_unit; a unique texture-space UV layout: the mesh's own, or one
generated with xatlas (dermis.geometry.texture_space) while the material keeps the asset's UVs.
Known failure modes: UV seams (mitigated by coverage-normalised blurs and gutter dilation; light
does not cross a seam: a layout should keep seams out of lit/shadowed junctions, as the procedural head's
does on its face, dermis.geometry.atlas join_boxes), stretch varying faster than the blur width, translucency sums all lights'
irradiance at the far face (every light and the ambient) through the thickness along -N only: light
entering elsewhere (a nose wing lit from its side) is not transmitted. Interreflection is one
bounce, per vertex (K rays: Monte Carlo noise of a few % of the bounce, blurred by the diffusion),
of the skin mesh alone (non-skin surfaces neither block nor reflect), with the light leaving a hit
read from a ~2 mm box average of rho E instead of the diffused light, and without the Fresnel
factors (1 - rho_s a / pi) of the bounce's exit and entry.
Shaders: shaders/tsd/*.glsl; specular in shaders/common/brdf.glsl.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from dermis.errors import DermisError
from dermis.geometry.texture_space import UV_RANGE_TOLERANCE, texture_space_uvs
from dermis.gl.resources import maps_without_anisotropy, nearest_sampler, prepared, read_texture, set_uniform, uniform_bytes
from dermis.gl.shaders import program
from dermis.gl.interreflection import BounceGather, BounceSeries, bounce_level, read_per_vertex
from dermis.gl.irradiance_inputs import BOUNCE_INPUTS, IrradianceInputs, light_pass
from dermis.gl.seam_fill import SeamFill
from dermis.gl.subsurface_transfer import SubsurfaceTransfer, source_index
from dermis.gl.thickness import ThicknessTexture
from dermis.techniques.base import Frame, Technique, TranslucentOptions, bind_scene, check_bool, check_int, draw_mesh, draw_surfaces
from dermis.techniques.shared import (LIGHT_COUNT_DEFINE, MAX_GAUSSIANS, LightCountPrograms, OutputMode, Unit, bind_sampler, bind_sampler_array,
                                      light_signature, signature_defines,
                                      TRANSLUCENCY_MIN_VARIANCE_MM2, directional_albedo_uniforms, set_profile_uniforms,
                                      surface_detail_uniforms, thin_slab_law, translucency_uniforms)

def unpremultiply(a: np.ndarray) -> np.ndarray:
    """(rgb / a, a) where a > 0, else 0: a premultiplied texture of the blur chain as colours."""
    a = np.asarray(a, np.float32)
    cov = a[..., 3:4]
    with np.errstate(divide="ignore", invalid="ignore"):
        rgb = np.where(cov > 0, a[..., :3] / np.where(cov > 0, cov, 1.0), 0.0)
    return np.concatenate([rgb, cov], axis=-1).astype(np.float32)


OVERLAP_TOLERANCE = 0.01  # fraction of covered texels a UV layout may cover twice
# I_k is blurred and stored at the coarsest level where its sigma is still >= this many texels of
# that level and I_(k-1)'s >= LEVEL_MIN_INPUT_SIGMA_TEXELS (and no finer than I_(k-1)): _plan_levels
LEVEL_MIN_SIGMA_TEXELS = 1.2
TAP_STRETCH_PERCENTILE = 75.0
# a pass's taps per side reach this many sigmas at TAP_STRETCH_PERCENTILE: the first step's erf bins
# (FOOTPRINT) to 3 sigma, the later steps' sampled Gaussians, whose variance the correction tap makes
# exact (tsd/blur.frag), to TAP_REACH_SIGMAS
FOOTPRINT_REACH_SIGMAS = 3.0
TAP_REACH_SIGMAS = 2.5
LEVEL_MIN_INPUT_SIGMA_TEXELS = 0.5
# a light Gaussian (its largest normalised weight, over the channels, below LEVEL_LIGHT_WEIGHT) may go
# one level coarser: its I_k's share of the error a reduced level brings is small. On the head at
# 1024^2 (d'Eon's profile) I_4 (weights <= 0.113) then runs at level 1: the impulse error at the
# head's 0.49 mm texels went 0.45 -> 1.0-1.1 % (red) and the chain a level-0 pair cheaper; moving
# the heavy I_5 (red 0.358) too would give 2.8 % (benchmarks/RESULTS.md, round 4)
LEVEL_LIGHT_WEIGHT = 0.15
LEVEL_MIN_SIGMA_TEXELS_LIGHT = 0.65
LEVEL_MIN_INPUT_SIGMA_TEXELS_LIGHT = 0.35
# I_1 and I_2 come from one 3x3 pass (tsd/blur_narrow.frag) when both are at level 0 and I_2's sigma
# is at most this many texels at the NARROW_STRETCH_PERCENTILE of the stretch: there G(v_2)
# integrated over the texels has a variance <= 2/3 texel^2, what a 3-tap kernel [a, 1 - 2a, a] holds
# (where the stretch is larger the pass spaces its taps, as tsd/blur.frag does)
NARROW_MAX_SIGMA_TEXELS = 0.75
NARROW_STRETCH_PERCENTILE = TAP_STRETCH_PERCENTILE
NARROW_PASS = True
# the seam fill (dermis.geometry.seams) covers the gutter texels within SEAM_REACH_SIGMAS sqrt(2) of the
# widest step at each level (the V pass reads the U pass's output at gutter texels up to its reach
# away, each of which gathered along u as far: a square of the reach, whose corner is sqrt(2) out) at
# the SEAM_STRETCH_PERCENTILE of the stretch, + 2 texels (bilinear reads, the reduction's box)
SEAM_REACH_SIGMAS = 3.0
SEAM_STRETCH_PERCENTILE = 95.0


@dataclass(frozen=True)
class TsdOptions(TranslucentOptions):
    multires: bool = True  # wide Gaussians blurred at half or quarter resolution
    max_taps: int = 12  # taps per side of a blur at the resolution it runs at
    # the narrow Gaussians' share of the detail I_1's texels cannot hold, from the irradiance at each
    # pixel (tsd/final.frag with PIXEL_DETAIL, tsd/gaussians.glsl: diffuse_irradiance_detail)
    pixel_detail: bool = True
    # light across UV seams: each blur step's gutter texels beside a seam hold the neighbouring chart's
    # input at the same surface point (dermis.geometry.seams, dermis.gl.seam_fill; issue 12)
    seams: bool = True

    def validate(self, technique: str) -> None:
        super().validate(technique)
        check_bool(f"{technique}: multires", self.multires)
        check_int(f"{technique}: max_taps", self.max_taps, 1, 64)
        check_bool(f"{technique}: pixel_detail", self.pixel_detail)
        check_bool(f"{technique}: seams", self.seams)


# The lights whose sharp shadows (the specular's) the irradiance pass stores for the final pass
# (tsd/sharp_shadow.glsl: one RGBA8 target, coverage and three lights). A scene with more lights
# draws the per-sample programs (a shadow-map tap per light per screen sample): a second target
# would take the final pass to 17 samplers, past the 16 every GL 4.5 guarantees.
STORED_SHARP_SHADOWS = 3
# the shader storage binding of the triangles' texture-space UVs (tsd/triangle_uv.glsl)
TRIANGLE_UV_BINDING = 0
# the most Gaussians for which tsd/final.frag with PIXEL_DETAIL reads both the stored sharp shadows and
# the shadow atlas within the 16 guaranteed samplers (dermis.techniques.tsd.Tsd._final_program)
DETAIL_MAX_GAUSSIANS_STORED = 7
# ... and of the bounce per vertex and the index buffer (tsd/final.frag with PIXEL_DETAIL_BOUNCE)
BOUNCE_BINDING = 1
INDEX_BINDING = 2
# ... and of the corners' surface metric (tsd/final.frag with PIXEL_DETAIL: detail_texels_per_mm;
# dermis.gl.resources.GpuScene.corner_metric). A buffer, not the stretch map: the detail program's
# samplers are all in use with K = 7 (above), and GL 4.5 guarantees 8 storage blocks per fragment shader
CORNER_METRIC_BINDING = 3


def stores_sharp_shadows(light_count: int) -> bool:
    """Whether tsd reads the lights' sharp shadows from its texture-space pass (else per sample)."""
    return int(light_count) <= STORED_SHARP_SHADOWS


# The irradiance pass in two parts (dermis.gl.irradiance_inputs, as the shared bounce's rho E since
# round 11): the light-independent inputs rasterised once per content (product key
# "interreflection_inputs": mesh, layout, material, environment, directional albedo, size), then per
# lighting change one full-screen pass adding the lights. False: the one mesh raster per lighting
# change (tsd/irradiance.frag without SKIN_BOUNCE_*), kept as the reference the split is tested against
# (tests/test_tsd_pipeline.py) and drawn wherever p_irradiance is set (benchmarks swap shaders in).
SPLIT_IRRADIANCE = True
# the inputs' formats (IrradianceInputs order: P rho_s, N m, Ng E_a.b, c E_a.r, albedo^mix E_a.g,
# albedo^(1-mix)): 32-bit but albedo^(1-mix), which only scales rho E for the bounce's ~2 mm gather.
# Measured against main's one raster (5 scenes, 512 px, irradiance 1024^2, max |difference| / image
# max): these 4.2e-4..7.2e-4 (mean 4-8e-7: float rounding); targets 3-5 at 16 bits (c, the ambient,
# albedo^mix: 24 B/texel less) 8.5e-4..1.45e-3 (mean 3-15e-5). benchmarks/RESULTS.md, "Round 16, branch perf16"
INPUT_DTYPES = ("f4", "f4", "f4", "f4", "f4", "f2")


def irradiance_defines(light_count: int) -> dict:
    """tsd/irradiance.frag's defines for ``light_count`` lights: the stored sharp shadows at location
    1 where stores_sharp_shadows, then rho E and albedo^mix for the one bounce (SKIN_EXITANT_LOCATION,
    SKIN_ALBEDO_MIX_LOCATION: the irradiance pass writes them where it reads the albedo map anyway, so
    the bounce needs no mesh raster of its own for rho E and no albedo map read in its splat; dropped
    where the framebuffer has no such attachments, without interreflection)."""
    sharp = stores_sharp_shadows(light_count)
    first = 2 if sharp else 1
    return {**({"SKIN_SHARP_SHADOWS": STORED_SHARP_SHADOWS} if sharp else {}),
            "SKIN_EXITANT_LOCATION": first, "SKIN_ALBEDO_MIX_LOCATION": first + 1}


def light_pass_defines(light_count: int) -> dict:
    """The split pass's (SKIN_BOUNCE_FROM_INPUTS) defines: irradiance_defines's outputs less albedo^mix,
    which is an input (IrradianceInputs' fifth target) that the bounce's splat reads itself."""
    d = irradiance_defines(light_count)
    d.pop("SKIN_ALBEDO_MIX_LOCATION")
    return {**d, "SKIN_BOUNCE_FROM_INPUTS": 1}


class TextureSpaceDiffusion(Technique):
    name = "tsd"
    description = "texture-space diffusion (d'Eon, Luebke & Enderton 2007): chained UV-space Gaussian blurs"
    Options = TsdOptions

    def __init__(self, renderer, **options):
        super().__init__(renderer, **options)
        ctx = self.ctx
        defines = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
        self.p_stretch = program(ctx, "tsd/uv_space.vert", "tsd/stretch.frag", defines)
        # the irradiance and final passes storing / reading the sharp shadows (at most
        # STORED_SHARP_SHADOWS lights); the per-sample pair compiled on a scene with more lights.
        # The irradiance program is compiled per light count (_irradiance_programs, called with the count).
        # p_irradiance, when set (benchmarks and tests swap shaders in), is drawn instead of it.
        self.p_irradiance = None
        # tsd/irradiance.frag per light count, its lights unrolled (LightCountPrograms), storing the
        # sharp shadows where stores_sharp_shadows(n), and the bounce's targets (irradiance_defines)
        self._irradiance_programs = LightCountPrograms(
            ctx, "tsd/uv_space.vert", "tsd/irradiance.frag", defines, per_count=irradiance_defines)
        # the split pass (SPLIT_IRRADIANCE): the light-independent inputs, then per lighting change the
        # full-screen light pass per light count; the program drawn is compiled up front
        self._inputs = IrradianceInputs(ctx, albedo_rest=True, dtypes=INPUT_DTYPES)
        # compiled per light signature as well (the lights' kinds and shadow kernels as constants:
        # shared.light_signature): the same floats, -7 % of the pass on the head (round 24, irr24)
        self._light_programs = LightCountPrograms(
            ctx, "common/fullscreen.vert", "tsd/irradiance.frag", defines, per_count=light_pass_defines,
            signature=True)
        (self._light_programs if SPLIT_IRRADIANCE else self._irradiance_programs).compile_for(renderer.scene)
        self.p_dilate = program(ctx, "common/fullscreen.vert", "tsd/dilate.frag", defines)
        self.p_down = program(ctx, "common/fullscreen.vert", "tsd/downsample.frag", defines)
        # a full-screen triangle: the pass reads only gl_FragCoord and textures, so rasterising the
        # mesh's layout (its vertex work and thin triangles) bought nothing; uncovered texels have
        # no far face in the bake and write T = 0, as the cleared target held
        self.p_trans = program(ctx, "common/fullscreen.vert", "tsd/translucency.frag", defines)
        self.p_trans_tent = program(ctx, "common/fullscreen.vert", "tsd/translucency_tent.frag", defines)
        # the final pass per light count, its lights unrolled (LightCountPrograms, as ssss's and
        # preintegrated's passes): its I_0 lights and specular read the light uniforms and stored sharp
        # shadows at constant indices; on llvmpipe -14 % of the pass at front-key's one light and 768 px,
        # -5 % at the head's three and 1024 px, the image bit-identical (round 23, final23)
        self._final_programs = LightCountPrograms(
            ctx, "common/mesh.vert", "tsd/final.frag",
            {**defines, "SHARP_SHADOW_READ": None, "TRIANGLE_UV_BINDING": TRIANGLE_UV_BINDING}).compile_for(renderer.scene)
        # ("per_sample", n) -> the final pass without the stored shadows; ("detail", stored, bounce, K, n, light_signature) -> PIXEL_DETAIL's
        # (n: the light count, unrolled as _final_programs')
        self._programs = {}
        self._detail_bounce = None  # None: no pixel detail this frame; else whether I_0 holds the bounce
        self._detail_buffer = None  # the bounce per vertex for PIXEL_DETAIL_BOUNCE (_bounce_buffer)
        self.p_combine = program(ctx, "common/fullscreen.vert", "tsd/combine.frag", defines)
        self.vaos = {p: ctx.vertex_array(p, []) for p in (self.p_dilate, self.p_down, self.p_combine, self.p_trans,
                                                         self.p_trans_tent)}
        self._blur_programs = {}  # (taps per side, footprint) -> program (blur.frag with TAPS unrolled)
        self._p_narrow = None  # tsd/blur_narrow.frag, compiled on first use
        self._narrow_key = None
        self._cache_key = None
        self._stretch_key = None
        self._frame_mesh = None
        self._plan = None  # (key, levels, step variances) of the blur chain (texture_space)
        self._size = None
        self.tex = {}
        self.levels = []
        self.median_stretch = None
        self.seam_stretch = None  # the stretch's SEAM_STRETCH_PERCENTILE (_seam_levels)
        self._transfer_level = -1  # the level the final pass reads the transfer's view term at; -1: none
        self.tap_stretch = None
        self.uv_overlap = None
        self._stretch_chain_key = None
        self._chain_passes = None  # ((chain key, dilated irradiance), the irradiance's prepared passes)
        self.thickness = ThicknessTexture(self.ctx)  # the texel thickness bake (light through thin parts)
        # the same-side transport an ear's thin, curled sheet adds to the flat profile, where the mesh
        # has a baked transfer (dermis.subsurface_transfer)
        self.transfer = SubsurfaceTransfer(self.ctx)
        self.seam_fill = SeamFill(self.ctx)  # light across UV seams (dermis.geometry.seams)
        # texel reads through the sampler (exact texel centres, the border clamped as texelFetch of a
        # clamped texel): cheaper than texelFetch on llvmpipe (tsd/blur.frag)
        self._nearest = nearest_sampler(ctx)
        self._own_filled = None  # (bake key, target) of the last whole translucency_own pass (tsd/translucency.frag)
        self._static_filled = None  # (key, target) of the last translucency_static pass (_translucency_static)
        self._p_trans_static = None
        self.hits = renderer.interreflection_hits  # the interreflection rays' hits (one bounce; the Renderer's)
        # (exitant, gather, splat, splat reading albedo^mix, the higher bounces), compiled on first use
        self._p_bounce = None
        self._bounce_added = None  # the per-vertex bounce the last splat added (the gather's or the series' target)
        self.bounce_level = None

    # ------------------------------------------------------------------ resources
    def _texture(self, key, size, components=4, dtype="f2"):
        t = self.tex.get(key)
        if t is not None and t.size == size:
            return t
        if t is not None:  # a new size: the framebuffers drawing into the old texture go with it
            for k in [k for k in self.tex if isinstance(k, tuple) and k[0] == "fbo" and id(t) in k[1:]]:
                self.tex.pop(k).release()
            t.release()
        t = self.ctx.texture(size, components, dtype=dtype)
        t.filter = (moderngl.LINEAR, moderngl.LINEAR)
        t.repeat_x = t.repeat_y = False
        self.tex[key] = t
        return t

    def _fbo(self, *textures):
        """The framebuffer drawing into ``textures`` (kept in self.tex while they live: _texture
        releases it with them, so an id in its key never outlives its texture)."""
        key = ("fbo", *(id(t) for t in textures))
        f = self.tex.get(key)
        if f is None:
            f = self.ctx.framebuffer(color_attachments=list(textures))
            f.viewport = (0, 0, *textures[0].size)
            self.tex[key] = f
        return f

    def release_textures(self):
        """Free every texture-space target; what was built in them is gone, so the keys it was
        built with are forgotten too (the next frame rebuilds, whatever its inputs)."""
        for k, o in list(self.tex.items()):  # framebuffers first, then their textures
            if isinstance(k, tuple) and k[0] == "fbo":
                o.release()
        for k, o in list(self.tex.items()):
            if not (isinstance(k, tuple) and k[0] == "fbo"):
                o.release()
        self.tex = {}
        self.scene_changed()
        self._stretch_chain_key = None
        self._chain_passes = None
        self._narrow_key = None
        self._own_filled = None
        self._static_filled = None
        self._inputs.shrink()
        self.thickness.release()
        self.transfer.release()
        self.seam_fill.release()

    def scene_changed(self):
        self._cache_key = None
        self._stretch_key = None
        self._plan = None
        self._chain_passes = None

    # ------------------------------------------------------------------ passes
    def _fullscreen(self, prog, target_tex):
        fbo = self._fbo(target_tex)
        fbo.use()
        fbo.viewport = (0, 0, *target_tex.size)
        self.vaos[prog].render(moderngl.TRIANGLES, vertices=3)

    def _pass(self, prog, targets, uniforms: dict, samplers: dict, nearest=False) -> tuple:
        """A full-screen pass prepared for :meth:`_draw`: (vertex array, framebuffer, uniform
        writes, texture binds). ``uniforms``: name -> value, kept as the bytes set_uniform would
        write; ``samplers``: name -> (texture, unit); ``nearest``: the textures are read through
        the NEAREST, CLAMP_TO_EDGE sampler object (shaders that read texel centres with textureLod:
        tsd/blur.frag), bound for the pass only. Only what the program uses is kept."""
        writes, binds = [], []
        for name, (tex, unit) in samplers.items():
            if prog.get(name, None) is not None:
                binds.append((tex, unit, self._nearest if nearest else None))
                uniforms = {**uniforms, name: unit}
        for name, value in uniforms.items():
            u = prog.get(name, None)
            if u is not None:
                writes.append((u, uniform_bytes(u, value)))
        targets = targets if isinstance(targets, tuple) else (targets,)
        return self.vaos[prog], self._fbo(*targets), tuple(writes), tuple(binds)

    @staticmethod
    def _draw(passes):
        """Draw prepared passes (:meth:`_pass`) in order; a uniform is written only when its
        program holds another value (set_uniform's rule: the bytes written are in ``extra``)."""
        bound = {}  # unit -> the sampler object bound there (cleared at the end: later passes read the textures' own filters)
        for p in passes:
            if callable(p):  # a seam fill (_seam_fill)
                p()
                continue
            vao, fbo, writes, binds = p
            for u, data in writes:
                if u.extra != data:
                    u.write(data)
                    u.extra = data
            for tex, unit, sampler in binds:
                tex.use(unit)
                if bound.get(unit) is not sampler:
                    if sampler is None:
                        bound.pop(unit).clear(unit)
                    else:
                        sampler.use(unit)
                        bound[unit] = sampler
            fbo.use()
            vao.render(moderngl.TRIANGLES, vertices=3)
        for unit, sampler in bound.items():
            sampler.clear(unit)

    def _uv_pass(self, frame, prog, target_tex, clear=True):
        targets = target_tex if isinstance(target_tex, tuple) else (target_tex,)
        fbo = self._fbo(*targets)
        fbo.use()
        fbo.viewport = (0, 0, *targets[0].size)
        if clear:
            fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        frame.gpu.vao(prog).render(moderngl.TRIANGLES)

    def _stretch(self, frame):
        """S_0: texels per mm along u, v; gutters filled with the nearest island's value (CPU, once)."""
        from scipy import ndimage

        S = self.renderer.irradiance_size
        raw = self._texture("stretch_raw", (S, S), 4, "f4")
        set_uniform(self.p_stretch, "uMmPerUnit", float(frame.scene.mm_per_unit))
        self._uv_pass(frame, self.p_stretch, raw)
        data = np.frombuffer(raw.read(), np.float32).reshape(S, S, 4).copy()
        cov = data[:, :, 3] > 0.5
        if not cov.any():
            raise DermisError(f"{frame.scene.mesh.source}: mesh covers no texel of its UV layout (all UVs outside [0, 1]?)")
        # the count below sees only [0, 1]^2 (the viewport): UVs beyond it (REPEAT tiling) would pass it
        m = frame.scene.mesh
        uv_ts = texture_space_uvs(m)
        lo, hi = float(np.min(uv_ts)), float(np.max(uv_ts))
        if lo < -UV_RANGE_TOLERANCE or hi > 1.0 + UV_RANGE_TOLERANCE:
            raise DermisError(f"{m.source}: UVs run outside [0, 1] (from {lo:.3g} to {hi:.3g}, a repeating texture?); "
                              f"technique '{self.name}' needs a unique UV layout: set [mesh] texture_space_uv = \"auto\" "
                              f"or \"generate\" for a generated one, or use --technique ssss or lambert")
        # texture space needs a unique layout: count coverage with additive blending
        count = self._texture("uv_count", (S, S), 4, "f4")
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        self._uv_pass(frame, self.p_stretch, count)
        self.ctx.disable(moderngl.BLEND)
        counts = np.frombuffer(count.read(), np.float32).reshape(S, S, 4)[:, :, 3]
        overlap = float((counts > 1.5).sum() / max(cov.sum(), 1))
        self.uv_overlap = overlap
        if overlap > OVERLAP_TOLERANCE:
            raise DermisError(f"{frame.scene.mesh.source}: UV layout overlaps itself ({overlap:.1%} of covered texels are "
                              f"covered twice); technique '{self.name}' needs a unique UV layout: set [mesh] texture_space_uv = "
                              f"\"auto\" or \"generate\" for a generated one, or use --technique ssss or lambert")
        # one-texel islands' edges: derivatives are unreliable at triangle borders; take the median
        vals = data[cov][:, :2]
        self.median_stretch = float(np.median(vals))
        # the tap count of each blur pass is set for TAP_STRETCH_PERCENTILE % of the layout; where the
        # stretch is larger the taps space out (integer steps, the kernel's variance still exact:
        # tsd/blur.frag) instead of every texel paying for more
        self.tap_stretch = float(np.percentile(vals, TAP_STRETCH_PERCENTILE))
        self.seam_stretch = float(np.percentile(vals, SEAM_STRETCH_PERCENTILE))
        self.narrow_stretch = np.percentile(vals, NARROW_STRETCH_PERCENTILE, axis=0).astype(np.float64)
        # per axis too: a layout squashed along one axis adds more variance (mm^2) along it when
        # reduced 2x2 (_step_variances)
        self.median_stretch_uv = np.median(vals, axis=0).astype(np.float64)
        idx = ndimage.distance_transform_edt(~cov, return_distances=False, return_indices=True)
        filled = data[idx[0], idx[1]]
        # coverage 1 everywhere: the gutters hold the nearest island's stretch, and the blur chain
        # (premultiplied, tsd/blur.frag) carries the stretch map as it is
        filled[:, :, 3] = 1.0
        s0 = self._texture("stretch_0", (S, S), 4, "f4")
        s0.write(np.ascontiguousarray(filled).tobytes())
        self._stretch0 = np.ascontiguousarray(filled[:, :, :2])  # texels per mm (u, v), for _narrow_weights
        self._narrow_key = None

    def _stretch_uv(self):
        stretch_uv = getattr(self, "median_stretch_uv", None)
        if stretch_uv is None:
            stretch_uv = np.full(2, self.median_stretch or 1.0)
        return np.maximum(np.asarray(stretch_uv, np.float64), 1e-9)

    @staticmethod
    def _box_variance(level_from, level_to, texel0_mm):
        """Variance (mm^2 per axis) the 2x2 box reductions from level_from to level_to add: a box of
        two texels of level l - 1 adds (2^(l-1) texel)^2 / 4."""
        return sum(0.25 * ((2.0 ** (l - 1)) * texel0_mm) ** 2 for l in range(level_from + 1, level_to + 1))

    @staticmethod
    def _read_variance(level, texel0_mm):
        """Variance (mm^2 per axis) that reading a level-L texture with bilinear filtering adds, on
        average over the sample's position in a texel: integral of f (1 - f) df = 1/6 texel^2. At
        level 0 the reference is the texel itself (none added)."""
        return 0.0 if level == 0 else ((2.0 ** level) * texel0_mm) ** 2 / 6.0

    def _plan_levels(self, profile, S):
        """Resolution level of each blurred irradiance I_k: the coarsest level where (at the median
        stretch) I_k's own sigma is >= LEVEL_MIN_SIGMA_TEXELS texels (it holds no finer detail, and
        bilinear reads of it are smooth: d'Eon & Luebke 2007, 14.4.3), I_(k-1)'s sigma is
        >= LEVEL_MIN_INPUT_SIGMA_TEXELS texels of it (what reducing it there aliases, the step's blur
        and I_k's own sigma of >= 1.2 texels take down to < 0.1%), no
        finer than I_(k-1)'s level, and the step's variance stays >= 0 once the reductions and
        the bilinear read take theirs (_step_variances). Each level divides a pass's texels by 4."""
        if not (self.options.multires and self.median_stretch):
            return [0] * profile.k
        v = np.concatenate([[0.0], profile.variances_mm2])
        texel0 = 1.0 / self._stretch_uv()  # mm per level-0 texel along u, v
        t0 = float(np.max(texel0))
        max_level = max(0, int(math.log2(max(S, 16) / 16)))
        heavy = np.max(np.asarray(profile.normalized().weights, np.float64), axis=1) >= LEVEL_LIGHT_WEIGHT
        levels, prev = [], 0
        for k in range(1, len(v)):
            lvl = prev
            own, inp = ((LEVEL_MIN_SIGMA_TEXELS, LEVEL_MIN_INPUT_SIGMA_TEXELS) if heavy[k - 1] else
                        (LEVEL_MIN_SIGMA_TEXELS_LIGHT, LEVEL_MIN_INPUT_SIGMA_TEXELS_LIGHT))
            for cand in range(max_level, prev, -1):
                tex = (2.0 ** cand) * t0
                ok = (math.sqrt(v[k]) >= own * tex
                      and math.sqrt(v[k - 1]) >= inp * tex
                      and np.all(self._steps_for(v, levels + [cand], texel0)[-1] >= 0.0))
                if ok:
                    lvl = cand
                    break
            levels.append(lvl)
            prev = lvl
        return levels

    def _steps_for(self, v, levels, texel0):
        """(K, 2) per-axis step variances for ``levels``, before clipping at 0."""
        out, prev = [], 0
        for k, lvl in enumerate(levels, start=1):
            step = (v[k] - v[k - 1]) - (np.array([self._read_variance(lvl, t) for t in texel0])
                                        - np.array([self._read_variance(prev, t) for t in texel0])) \
                - np.array([self._box_variance(prev, lvl, t) for t in texel0])
            out.append(step)
            prev = lvl
        return np.array(out)

    def _step_variances(self, profile, levels):
        """Per-step variances (K, 2) along u and v such that I_k, read with bilinear filtering,
        has variance v_k: the step's v_k - v_(k-1), less what the 2x2 reductions between levels
        add along each axis (a 2-texel box adds texel_mm^2 / 4; a layout squashed along one axis has
        longer texels (mm) along it: with one isotropic correction a UV layout squashed 2:1 gave
        an impulse response elongated 3% along the squashed axis), less the change in the variance
        the bilinear read of a reduced level adds (_read_variance)."""
        v = np.concatenate([[0.0], profile.variances_mm2])
        return np.maximum(self._steps_for(v, levels, 1.0 / self._stretch_uv()), 0.0)

    def _down(self, src, key, level):
        """(the 2x2 reduction of ``src``, its pass)."""
        size = (max(1, src.size[0] // 2), max(1, src.size[1] // 2))
        dst = self._texture(key, size)
        return dst, [self._pass(self.p_down, dst, {}, {"uSource": (src, 0)}, nearest=True)]

    def _blur_program(self, sigma_mm, level, footprint, max_taps=None):
        """blur.frag compiled with the fewest taps per side that reach 3 sigma at the widest
        stretch that TAP_STRETCH_PERCENTILE % of the layout has (at most max_taps; wider kernels space their taps
        further), for the first step (footprint: erf bins) or a later one (sampled, exact variance).
        Compiled on first use."""
        widest = sigma_mm * (self.tap_stretch or self.median_stretch or 1.0) * 2.0 ** -level
        cap = max_taps or self.options.max_taps
        reach = FOOTPRINT_REACH_SIGMAS if footprint else TAP_REACH_SIGMAS
        need = min(math.ceil(reach * widest), cap)
        taps = max(1, min(need, cap))
        key = (taps, bool(footprint), reach)
        prog = self._blur_programs.get(key)
        if prog is None:
            defines = {"MAX_GAUSSIANS": MAX_GAUSSIANS, "TAPS": taps, "REACH": f"{float(reach):.6f}"}
            if footprint:
                defines["FOOTPRINT"] = 1
            prog = program(self.ctx, "common/fullscreen.vert", "tsd/blur.frag", defines)
            self._blur_programs[key] = prog
            self.vaos[prog] = self.ctx.vertex_array(prog, [])
        return prog

    def _blur(self, src, stretch, sigma_mm, level, out_key, footprint=False, max_taps=None):
        """(the blurred texture, its U and V passes); ``sigma_mm`` a number or a (u, v) pair.
        Premultiplied in and out."""
        sigma_u, sigma_v = np.broadcast_to(np.asarray(sigma_mm, np.float64), (2,))
        size = src.size
        tmp = self._texture(("tmp", out_key), size)
        out = self._texture(out_key, size)
        prog = self._blur_program(max(sigma_u, sigma_v), level, footprint, max_taps)
        common = {"uLevelScale": float(2.0 ** -level)}
        # the U pass is told the V pass's sigma: V steps orthogonally to u on the surface and its reads
        # at fractional u add variance along u that U takes off (tsd/blur.frag)
        return out, [self._pass(prog, tmp, {**common, "uSigmaMm": float(sigma_u), "uSigmaOtherMm": float(sigma_v),
                                            "uDirection": (1.0, 0.0)},
                                {"uStretch": (stretch, 1), "uSource": (src, 0)}, nearest=True),
                     self._pass(prog, out, {**common, "uSigmaMm": float(sigma_v), "uSigmaOtherMm": 0.0, "uDirection": (0.0, 1.0)},
                                {"uStretch": (stretch, 1), "uSource": (tmp, 0)}, nearest=True)]

    def _narrow_ok(self, levels, steps):
        """Whether I_1 and I_2 come from one pass (tsd/blur_narrow.frag): both at level 0 and I_2's
        sigma (per axis) <= NARROW_MAX_SIGMA_TEXELS at the NARROW_STRETCH_PERCENTILE of the stretch."""
        ns = getattr(self, "narrow_stretch", None)
        if not NARROW_PASS or ns is None or len(levels) < 2 or levels[0] != 0 or levels[1] != 0:
            return False
        v2 = np.asarray(steps[0]) + np.asarray(steps[1])  # mm^2 along u, v (level 0: nothing taken off)
        return bool(np.all(np.sqrt(v2) * ns <= NARROW_MAX_SIGMA_TEXELS))

    @staticmethod
    def binned_variance(sigma_texels):
        """Variance (texel^2) of a Gaussian of ``sigma_texels`` integrated over unit bins centred on
        the texels: 2 sum_j j^2 m_j over the bins' masses m_j (j = 1..8, binned_gaussian_1d of
        dermis.verification) below 1 texel, Sheppard's sigma^2 + 1/12 from there (exact to < 1e-6)."""
        from scipy.special import erf

        sig = np.asarray(sigma_texels, np.float64)
        out = np.array(sig * sig + 1.0 / 12.0)
        small = ~(sig >= 1.0)  # the bins' sum only where it is used
        s = np.sqrt(2.0 * np.maximum(sig[small], 1e-6) ** 2)
        # binned_gaussian_1d(j, var, 1) = (erf((j + 1/2) / s) - erf((j - 1/2) / s)) / 2: neighbouring bins
        # share an edge, so 9 erf a texel, not 16 (the same values, bit for bit; 1.8 s a 1024^2 head map)
        edge = [erf((i + 0.5) / s) for i in range(9)]  # (i + 1/2) / s, i = 0..8: the edges j -+ 1/2
        out[small] = sum(2.0 * j * j * (0.5 * (edge[j] - edge[j - 1])) for j in range(1, 9))
        return out

    def _narrow_weights(self, v1, v2):
        """(S, S, 4) float32: the binned variances (texel^2) of I_1 along u, v and of I_2 along u, v
        per texel (v1, v2 in mm^2 per axis) from the level-0 stretch (tsd/blur_narrow.frag makes its
        kernels from them); uploaded when the stretch or the variances change."""
        key = (self._stretch_key, tuple(np.round(v1, 12)), tuple(np.round(v2, 12)))
        old = self.tex.get("narrow_weights")
        tex = self._texture("narrow_weights", self.tex["stretch_0"].size, 4, "f4")
        if key != self._narrow_key or tex is not old:
            st = self._stretch0
            a = np.concatenate([self.binned_variance(np.sqrt(v1) * st), self.binned_variance(np.sqrt(v2) * st)], axis=-1)
            tex.write(np.ascontiguousarray(a, np.float32).tobytes())
            self._narrow_key = key
        return tex

    def _blur_narrow(self, dil, steps):
        """(I_2, the pass): I_1 and I_2 from the dilated irradiance in one pass with two targets."""
        v1 = np.asarray(steps[0], np.float64)
        weights = self._narrow_weights(v1, v1 + np.asarray(steps[1], np.float64))
        out1 = self._texture(("blur", 0), dil.size)
        out2 = self._texture(("blur", 1), dil.size)
        if self._p_narrow is None:
            self._p_narrow = program(self.ctx, "common/fullscreen.vert", "tsd/blur_narrow.frag", {"MAX_GAUSSIANS": MAX_GAUSSIANS})
            self.vaos[self._p_narrow] = self.ctx.vertex_array(self._p_narrow, [])
        return out2, [self._pass(self._p_narrow, (out1, out2), {}, {"uSource": (dil, 0), "uWeights": (weights, 1)},
                                  nearest=True)]

    def _blur_chain(self, dil, levels, steps):
        """I_1..I_K from the dilated irradiance: step k blurs I_(k-1) by variance steps[k] at
        resolution level levels[k]; the stretch map goes through the same chain (once per mesh).
        The irradiance's passes (programs, framebuffers, uniform bytes, textures) are prepared
        once per plan, stretch, options and targets, and drawn from that list every frame."""
        # the options too: the stretch's blurs use max_taps's programs (a fresh Renderer's stretch
        # chain is blurred with the current options, so a change must redo it)
        seams = self._seam_levels(levels, steps)
        chain_key = (self._stretch_key, tuple(levels), tuple(np.round(steps, 12).ravel()), self.options, seams)
        redo_stretch = chain_key != self._stretch_chain_key
        passes_key = (chain_key, dil)
        if not redo_stretch and self._chain_passes is not None and self._chain_passes[0] == passes_key:
            self._draw(self._chain_passes[1])
            return
        passes = []  # the irradiance's, drawn after the stretch's (which they read)
        src, st = dil, self.tex["stretch_0"]
        level = 0
        narrow = self._narrow_ok(levels, steps)
        if narrow:
            src, p = self._seam_fill(src, 0, float(np.sqrt(np.max(np.asarray(steps[0]) + np.asarray(steps[1])))))
            passes += p
            src, p = self._blur_narrow(src, steps)
            passes += p
        for k, (lvl, var) in enumerate(zip(levels, steps)):
            while level < lvl:
                level += 1
                src, p = self._down(src, ("down", k, level), level)
                passes += p
                if redo_stretch:
                    st, p = self._down(st, ("stretch_down", k, level), level)
                    self._draw(p)
                else:
                    st = self.tex[("stretch_down", k, level)]
            sigma = np.sqrt(var)  # (u, v), mm
            if redo_stretch:
                st, p = self._blur(st, st, sigma, level, ("stretch", k))
                self._draw(p)
            else:
                st = self.tex[("stretch", k)]
            if not (narrow and k < 2):
                src, p = self._seam_fill(src, level, float(np.max(sigma)))
                passes += p
                src, p = self._blur(src, st, sigma, level, ("blur", k), footprint=(k == 0))
                passes += p
        self._draw(passes)
        self._stretch_chain_key = chain_key
        self._chain_passes = (passes_key, passes)

    def _seam_levels(self, levels, steps):
        """The seam fill's key for this plan (None: no fill): the layout (the stretch's key: mesh, scale,
        size) and each level's reach in its texels; the targets are built here when it changes."""
        if not self.options.seams or self._frame_mesh is None:
            return None
        st = self.seam_stretch or self.median_stretch or 1.0
        reach = {}
        for k, (lvl, var) in enumerate(zip(levels, steps)):
            r = SEAM_REACH_SIGMAS * math.sqrt(2.0) * float(np.sqrt(np.max(var))) * st * 2.0 ** -lvl + 2.0
            reach[int(lvl)] = max(reach.get(int(lvl), 0), int(math.ceil(r)))
        if self._narrow_ok(levels, steps):  # I_1, I_2 from the level-0 input in one pass
            r = SEAM_REACH_SIGMAS * math.sqrt(2.0) * float(np.sqrt(np.max(steps[0] + steps[1]))) * st + 2.0
            reach[0] = max(reach.get(0, 0), int(math.ceil(r)))
        key = (self._stretch_key, tuple(sorted(reach.items())))
        S = self.tex["stretch_0"].size[0]
        return key if self.seam_fill.prepare(key, self._frame_mesh, S, reach) else None

    def _seam_fill(self, src, level, sigma_mm):
        """(``src``, the pass filling its seam texels in place as far as a step of ``sigma_mm`` (its
        widest axis) at ``level`` reaches: SEAM_REACH_SIGMAS sqrt(2) sigma + 2 texels at the median
        stretch; none where the level has no seam: dermis.gl.seam_fill)."""
        if not (self.options.seams and self.seam_fill.filled(level)):
            return src, []
        reach_mm = SEAM_REACH_SIGMAS * math.sqrt(2.0) * sigma_mm + 2.0 * 2.0 ** level / (self.median_stretch or 1.0)
        reach = reach_mm / float(self._frame_mesh_mm)
        if self.seam_fill.prepare_step(level, reach) == 0:
            return src, []
        fbo, fill = self._fbo(src), self.seam_fill
        return src, [lambda: fill.draw(src, fbo, level, reach)]

    def _profile_uniforms(self, prog, profile, first_unit, frame_keys):
        """The profile (common/profile.glsl) and its blurred irradiances I_k (tsd/gaussians.glsl)
        from ``first_unit`` on; entries past K repeat I_K (never read: the loops stop at K)."""
        K = profile.k
        n = prog["uBlur"].array_length if prog.get("uBlur", None) is not None else MAX_GAUSSIANS  # the program's MAX_GAUSSIANS
        blurs = tuple(self.tex[("blur", min(k, K - 1))] for k in range(n))

        def setup(prog):
            set_profile_uniforms(prog, profile, n)
            bind_sampler_array(prog, "uBlur", blurs, first_unit)
        # written when the profile's content or a blur target changes; the targets bound every frame
        prepared(prog, "profile", (frame_keys["profile_tables"], blurs, first_unit), setup)

    def texture_space(self, frame: Frame, irradiance: np.ndarray | None = None):
        """Run the view-independent passes. ``irradiance`` (S, S, 4) float, row 0 = top (v = 1),
        replaces the rendered irradiance (rgb, alpha = coverage): used by the numeric tests."""
        scene = frame.scene
        profile = scene.profile
        if profile.k > MAX_GAUSSIANS:
            raise DermisError(f"profile '{profile.name}' has {profile.k} Gaussians; tsd supports at most {MAX_GAUSSIANS}")
        S = self.renderer.irradiance_size
        timer = frame.timer
        self._frame_mesh = scene.mesh  # the layout the seam fill maps (_seam_levels)
        self._frame_mesh_mm = float(scene.mm_per_unit)
        stretch_key = frame.keys["stretch"]
        if stretch_key != self._stretch_key:
            with timer("tsd_stretch"):
                self._stretch(frame)
            self._stretch_key = stretch_key
            self._stretch_chain_key = None
            frame.passes_run.append("tsd_stretch")
        # the chain's plan depends on the profile, the size and the stretch only: not re-planned per frame
        plan_key = (self._stretch_key, frame.keys["profile_tables"], S, self.options.multires)
        if self._plan is None or self._plan[0] != plan_key:
            levels = self._plan_levels(profile, S)
            self._plan = (plan_key, levels, self._step_variances(profile, levels))
        _, levels, steps = self._plan
        self.levels = levels
        # irradiance (the uniforms and bindings set before the timed region: Python, no GPU work)
        irr = self._texture("irradiance", (S, S))
        # the lights' sharp shadows, for the final pass's specular (tsd/sharp_shadow.glsl)
        prog, _ = self._shading_programs(frame)
        split = self._split_irradiance()
        if split:  # the light-independent inputs, once per content (timed on their own)
            self._inputs.draw(frame, (S, S), pass_name="tsd_irradiance_inputs")
        targets = (irr, self._texture("sharp_shadow", (S, S), 4, "f1")) if stores_sharp_shadows(frame.lights.count) else (irr,)
        # the one bounce (an override is the whole irradiance: nothing is added to it); rho E and
        # albedo^mix from this pass where its program is the technique's own (irradiance_defines)
        bounce = irradiance is None and getattr(scene, "interreflection", True)
        bounce_targets = bounce and self.p_irradiance is None
        if bounce_targets:
            targets += (self._texture(("bounce_exitant", 0), (S, S)),)
            if not split:  # the split pass's albedo^mix is an input (IrradianceInputs)
                targets += (self._texture("albedo_mix", (S, S)),)
        bind_scene(frame, prog)
        if split:
            self._inputs.bind(prog, Unit.FIRST_FREE)
        else:
            directional_albedo_uniforms(prog, scene)
        if irradiance is not None:
            a = np.ascontiguousarray(np.asarray(irradiance, np.float32)[::-1])
            if a.shape != (S, S, 4):
                raise ValueError(f"irradiance override must be {(S, S, 4)}, got {a.shape}")
        with timer("tsd_irradiance"):
            if split:  # every texel written: 0 off the layout, as the raster's clear
                light_pass(self.ctx, self.vaos, prog, self._fbo(*targets), (S, S))
            else:
                # a texture-space raster: the maps' footprint is square, anisotropy only costs
                with maps_without_anisotropy(frame.gpu, surfaces=False):
                    self._uv_pass(frame, prog, targets)
            if irradiance is not None:  # the override replaces the irradiance; the shadows stay the raster's
                irr.write(a.astype(np.float16).tobytes())
        # the final pass adds the narrow Gaussians' detail from I_0 at each pixel (PIXEL_DETAIL) where
        # I_0 is the irradiance pass's own: not where an override replaced it
        self._detail_bounce = bounce if irradiance is None and self.options.pixel_detail else None
        # one bounce between skin surfaces, added to I_0 before the dilation and the blurs
        if bounce:
            albedo_mix = self._inputs.textures[BOUNCE_INPUTS - 1] if split else self.tex.get("albedo_mix")
            self._interreflection(frame, irr, bounce_targets, albedo_mix)
            if self._detail_bounce:
                self._bounce_buffer()
        with timer("tsd_irradiance"):
            dil = self._texture("irradiance_dilated", (S, S))
            self._draw([self._pass(self.p_dilate, dil, {}, {"uSource": (irr, 0)}, nearest=True)])
        frame.passes_run.append("tsd_irradiance")
        # chained blurs of the irradiance and (once per mesh) of the stretch
        with timer("tsd_blur"):
            self._blur_chain(dil, levels, steps)
        frame.passes_run.append("tsd_blur")
        # translucency (texture space, half resolution)
        trans = self._texture("translucency", (max(S // 2, 1), max(S // 2, 1)))
        if self.options.translucency:
            thickness = self.thickness.get(frame, trans.size[0])
            with timer("tsd_translucency"):
                static = self._translucency_static(frame, thickness, trans.size)
                prog = self.p_trans
                translucency_uniforms(prog, True, self.options.translucency_strength, frame.scene)
                self._profile_uniforms(prog, profile, Unit.FIRST_FREE, frame.keys)
                # past the blurs' units
                bind_sampler(prog, "uThickness", thickness, Unit.FIRST_FREE + MAX_GAUSSIANS + 1)
                bind_sampler(prog, "uStatic", static, Unit.FIRST_FREE + MAX_GAUSSIANS + 2)
                own = self._texture("translucency_own", trans.size)
                # where the bake has no far face the texel's value is fixed by the bake: drawn once
                filled = self._own_filled is not None and self._own_filled[0] == self.thickness.key and self._own_filled[1] is own
                set_uniform(prog, "uFarFaceOnly", int(filled))
                self._fullscreen(prog, own)
                self._own_filled = (self.thickness.key, own)
                bind_sampler(self.p_trans_tent, "uSource", own, 0)
                self._fullscreen(self.p_trans_tent, trans)
            frame.passes_run.append("tsd_translucency")
            # + the baked transfer of thin, curled parts (dermis.gl.subsurface_transfer; nothing without a
            # bake), timed on its own: a pass of its own content, not the far face's
            with timer("tsd_subsurface_transfer"):
                added = self.transfer.add(frame, self._fbo(trans), trans.size,
                                          self.tex[("blur", source_index(profile.variances_mm2))])
            if added:
                frame.passes_run.append("tsd_subsurface_transfer")
            # the final pass adds the view term at the same level (common/subsurface_transfer.glsl)
            self._transfer_level = self.transfer.read_level(trans.size) if added else -1
        else:
            self._fbo(trans).clear(0.0, 0.0, 0.0, 0.0)
            self._transfer_level = -1

    def _translucency_static(self, frame, thickness, size):
        """What of the light through thin parts does not depend on the lighting, per texel
        (tsd/translucency.frag with TRANSLUCENCY_STATIC: the slab law over the wide weights, the
        surface distance to the far face), redrawn when the bake, the stretch, the profile or the
        slab law changes."""
        albedo, law = thin_slab_law(frame.scene)
        key = (self.thickness.key, self._stretch_key, frame.keys["profile_tables"], TRANSLUCENCY_MIN_VARIANCE_MM2,
               tuple(float(x) for a in (albedo, law.reduced_albedo, law.kappa_per_mm, law.source_depth_mm,
                                        law.extrapolation_mm) for x in np.ravel(a)))
        tex = self._texture("translucency_static", size, 4, "f4")
        if self._static_filled is not None and self._static_filled[0] == key and self._static_filled[1] is tex:
            return tex
        if self._p_trans_static is None:
            self._p_trans_static = program(self.ctx, "common/fullscreen.vert", "tsd/translucency.frag",
                                           {"MAX_GAUSSIANS": MAX_GAUSSIANS, "TRANSLUCENCY_STATIC": 1})
            self.vaos[self._p_trans_static] = self.ctx.vertex_array(self._p_trans_static, [])
        prog = self._p_trans_static
        translucency_uniforms(prog, True, 1.0, frame.scene)
        self._profile_uniforms(prog, frame.scene.profile, Unit.FIRST_FREE, frame.keys)
        # surface distance to the far face (uv distance / stretch); past the blurs' units
        bind_sampler(prog, "uStretch", self.tex["stretch_0"], Unit.FIRST_FREE + MAX_GAUSSIANS)
        bind_sampler(prog, "uThickness", thickness, Unit.FIRST_FREE + MAX_GAUSSIANS + 1)
        self._fullscreen(prog, tex)
        self._static_filled = (key, tex)
        return tex

    def _shading_programs(self, frame):
        """(irradiance, final) programs for the frame's lights: storing and reading the sharp
        shadows where there are at most STORED_SHARP_SHADOWS lights, else per sample. The irradiance
        program is the split's light pass where _split_irradiance, else the one raster's."""
        n = frame.lights.count
        if self.p_irradiance is not None:
            irr = self.p_irradiance
        else:  # the split's light pass, or the one raster (SPLIT_IRRADIANCE)
            irr = (self._light_programs if self._split_irradiance() else self._irradiance_programs)(n, frame.lights.lights)
        if stores_sharp_shadows(n):
            return irr, self._final_programs(n)
        key = ("per_sample", n)
        if key not in self._programs:
            self._programs[key] = program(self.ctx, "common/mesh.vert", "tsd/final.frag",
                                          {"MAX_GAUSSIANS": MAX_GAUSSIANS, "TRIANGLE_UV_BINDING": TRIANGLE_UV_BINDING,
                                           LIGHT_COUNT_DEFINE: n})
        return irr, self._programs[key]

    def _final_program(self, frame):
        """The final pass's program: PIXEL_DETAIL's (reading the stored sharp shadows or per sample, as
        _shading_programs; with PIXEL_DETAIL_BOUNCE where I_0 holds the bounce) when the last
        texture-space pass allows it, else the one _shading_programs gives."""
        if self._detail_bounce is None:
            return self._shading_programs(frame)[1]
        # with the stored sharp shadows it reads the shadow atlas as well (I_0's soft shadows): one sampler
        # more than _final_programs, so its blur array holds the profile's K textures, not MAX_GAUSSIANS
        # (16 guaranteed samplers: 7 shared, the translucency, the stored shadows and K <= 7 blurs);
        # a profile of 8 Gaussians or a scene of more than 3 lights takes the per-sample shadows
        k = frame.scene.profile.k
        stored = stores_sharp_shadows(frame.lights.count) and k <= DETAIL_MAX_GAUSSIANS_STORED
        n = frame.lights.count
        # per light signature too (the kinds and shadow kernels as constants, shared.light_signature): the
        # detail's per-pixel PCF of I_0's soft shadows folds as the light pass's does, the same floats
        # (benchmarks/results/round-24.md, sig24)
        sig = light_signature(frame.lights.lights)
        key = ("detail", stored, self._detail_bounce, k if stored else MAX_GAUSSIANS, n, sig)
        if key not in self._programs:
            defines = {"MAX_GAUSSIANS": key[3], "TRIANGLE_UV_BINDING": TRIANGLE_UV_BINDING, "PIXEL_DETAIL": 1,
                       "CORNER_METRIC_BINDING": CORNER_METRIC_BINDING, LIGHT_COUNT_DEFINE: n, **signature_defines(sig)}
            if stored:
                defines["SHARP_SHADOW_READ"] = None
            if self._detail_bounce:
                defines.update(PIXEL_DETAIL_BOUNCE=1, BOUNCE_BINDING=BOUNCE_BINDING, INDEX_BINDING=INDEX_BINDING)
            self._programs[key] = program(self.ctx, "common/mesh.vert", "tsd/final.frag", defines)
        return self._programs[key]

    def _bounce_buffer(self):
        """The bounce T per vertex that the last splat added (its target, vertex v at texel v in row
        order), copied into a shader storage buffer for tsd/final.frag (PIXEL_DETAIL_BOUNCE): a
        copy on the GPU, per lighting change."""
        tex = self._bounce_added
        nbytes = tex.width * tex.height * 16  # RGBA 32-bit float (dermis.gl.interreflection)
        buf = self._detail_buffer
        if buf is None or buf.size != nbytes:
            if buf is not None:
                buf.release()
            buf = self._detail_buffer = self.ctx.buffer(reserve=nbytes)
        tex.read_into(buf)
        return buf

    def _split_irradiance(self) -> bool:
        """Whether the irradiance pass is drawn from its light-independent inputs (SPLIT_IRRADIANCE),
        not the one mesh raster: only the technique's own program is split (p_irradiance, a shader
        swapped in by a benchmark or test, is drawn as a raster)."""
        return SPLIT_IRRADIANCE and self.p_irradiance is None

    def _bounce_level(self, S):
        """The level of rho E the gather reads (dermis.gl.interreflection.bounce_level at the
        stretch map's median)."""
        return bounce_level(self.median_stretch, S)

    def _interreflection(self, frame, irr, from_irradiance=False, albedo_mix=None):
        """Add the bounce light to the irradiance ``irr`` (I_0): rho E in texture space
        (``from_irradiance``: as the irradiance pass wrote it, with albedo^mix (``albedo_mix``, the
        texture the splat reads it from), irradiance_defines; else from I_0 by tsd/bounce_exitant.frag), reduced to _bounce_level, gathered per vertex over
        the baked rays (tsd/bounce_gather.frag), its higher orders added (BounceSeries: T = E_b + G E_b
        + ...) and T splatted into I_0 with additive blending
        (tsd/bounce_splat.frag). No pass reads the texture it writes."""
        self.hits.get(frame)  # the bake times itself: before this pass's timer
        if self._p_bounce is None:
            defines = {"MAX_GAUSSIANS": MAX_GAUSSIANS}
            splat = {**defines, "INTERREFLECTION": 1}
            self._p_bounce = (program(self.ctx, "tsd/uv_space.vert", "tsd/bounce_exitant.frag", defines),
                              BounceGather(self.ctx),
                              program(self.ctx, "tsd/uv_space.vert", "tsd/bounce_splat.frag", splat),
                              program(self.ctx, "tsd/uv_space.vert", "tsd/bounce_splat.frag", {**splat, "ALBEDO_MIX_TARGET": 1}),
                              BounceSeries(self.ctx))
        p_exit, p_gather, p_splat, p_splat_mix, series = self._p_bounce
        p_splat = p_splat_mix if from_irradiance else p_splat
        per_row = self.hits.per_row
        level = self._bounce_level(irr.size[0])
        self.bounce_level = level
        bind_scene(frame, p_exit)
        bind_scene(frame, p_splat)
        with frame.timer("tsd_interreflection"):
            if not from_irradiance:
                bind_sampler(p_exit, "uIrradiance", irr, Unit.FIRST_FREE)
                with maps_without_anisotropy(frame.gpu, surfaces=False):
                    self._uv_pass(frame, p_exit, self._texture(("bounce_exitant", 0), irr.size))
            src = self.tex[("bounce_exitant", 0)]
            # the one bounce reads the level the hits were merged for, as the shared bounce
            # (gl.interreflection.first_order_size: FIRST_ORDER_FINER_LEVELS finer than the ~2 mm
            # level of the layout's median stretch); its series reads the ~2 mm level
            first = max(int(round(math.log2(irr.size[0] / max(self.hits.cells, 1)))), 0)
            for lvl in range(1, first + 1):
                src, p = self._down(src, ("bounce_exitant", lvl), lvl)
                self._draw(p)
            p_gather.run(self.hits, src)
            # + the higher bounces (T = E_b + G E_b + ...): the splat adds their sum, which the
            # diffusion then spreads like every other light
            bounce = series.run(frame, self.hits, p_gather, level)
            self._bounce_added = bounce
            bind_sampler(p_splat, "uBounce", bounce, Unit.FIRST_FREE)
            if from_irradiance:
                bind_sampler(p_splat, "uAlbedoMix", albedo_mix, Unit.FIRST_FREE + 1)
            set_uniform(p_splat, "uVerticesPerRow", int(per_row))
            self.ctx.enable(moderngl.BLEND)
            self.ctx.blend_func = moderngl.ONE, moderngl.ONE
            with maps_without_anisotropy(frame.gpu, surfaces=False):
                self._uv_pass(frame, p_splat, irr, clear=False)
            self.ctx.disable(moderngl.BLEND)
        frame.passes_run.append("tsd_interreflection")

    def bounce_per_vertex(self) -> np.ndarray:
        """The bounce irradiance the last bounce pass added per mesh vertex, (n, 3): T, every order
        (dermis.gl.interreflection.BounceSeries; E_b alone where it takes one)."""
        return read_per_vertex(self._bounce_added, self.hits.vertex_count)

    def first_bounce_per_vertex(self) -> np.ndarray:
        """E_b of the last bounce pass per mesh vertex, (n, 3): the one bounce (tsd/bounce_gather.frag)."""
        return self._p_bounce[1].per_vertex(self.hits.vertex_count)

    def render(self, frame: Frame, output_mode: int = OutputMode.FULL) -> None:
        key = (frame.lighting_key, self.options)
        if key != self._cache_key:
            self.texture_space(frame)
            self._cache_key = key
        with frame.timer("tsd_final"):
            frame.target.use()
            self.ctx.enable(moderngl.DEPTH_TEST)
            self.ctx.disable(moderngl.CULL_FACE)
            prog = self._final_program(frame)
            bind_sampler(prog, "uTranslucency", self.tex["translucency"], Unit.FIRST_FREE)
            # the baked transfer's view term (images: this pass has no sampler left), at the level the
            # translucency target's add read the cosine grid; -1: none
            level = self._transfer_level
            set_uniform(prog, "uTransferLevel", float(level))
            self.transfer.bind_view(prog, level)
            self._profile_uniforms(prog, frame.scene.profile, Unit.FIRST_FREE + 1, frame.keys)
            if prog.get("uSharpShadow", None) is not None:  # _final_programs and its PIXEL_DETAIL variant
                bind_sampler(prog, "uSharpShadow", self.tex["sharp_shadow"], Unit.FIRST_FREE + 1 + MAX_GAUSSIANS)
            if self._detail_bounce is not None:
                # I_1's texels across (tsd/final.frag: detail_texels_per_mm), written when it changes
                texels = float(self.renderer.irradiance_size >> self.levels[0])
                prepared(prog, "detail_texels", texels, lambda p: set_uniform(p, "uDetailTexels", texels))
                frame.gpu.corner_metric().bind_to_storage_buffer(CORNER_METRIC_BINDING)
                if self._detail_bounce:
                    self._detail_buffer.bind_to_storage_buffer(BOUNCE_BINDING)
                    frame.gpu.ibo.bind_to_storage_buffer(INDEX_BINDING)
            surface_detail_uniforms(prog, frame.scene.material, output_mode)
            directional_albedo_uniforms(prog, frame.scene)
            # each triangle's texture-space UVs: a fragment reads tsd's textures on its own triangle
            # (tsd/triangle_uv.glsl: the pixel-centre UV of an edge-on triangle's edge sample)
            frame.gpu.triangle_uv_ts().bind_to_storage_buffer(TRIANGLE_UV_BINDING)
            draw_mesh(frame, prog)
        frame.passes_run.append("tsd_final")
        draw_surfaces(frame, output_mode)  # the non-skin surfaces, with depth testing

    def combined(self, frame: Frame) -> np.ndarray:
        """sum_k w_k I_k in texture space at the irradiance resolution, (S, S, 3), row 0 = top."""
        S = self.renderer.irradiance_size
        out = self._texture("combined", (S, S), 4, "f4")
        self._profile_uniforms(self.p_combine, frame.scene.profile, 0, frame.keys)
        self._fullscreen(self.p_combine, out)
        return self.read_texture(out)[:, :, :3]

    def blur_direct(self, frame: Frame, variance_mm2: float) -> np.ndarray:
        """The dilated raw irradiance blurred once with the full variance (level 0, unchained):
        the reference the chained I_k must equal."""
        out, passes = self._blur(self.tex["irradiance_dilated"], self.tex["stretch_0"], math.sqrt(variance_mm2), 0,
                                 "direct", footprint=True, max_taps=48)
        self._draw(passes)
        return self.read_texture(out)

    def blurred(self, k: int) -> np.ndarray:
        """I_(k+1) as stored (its level's resolution), (h, w, 4) with the colour normalised by the
        coverage (the chain is premultiplied: tsd/blur.frag), alpha = coverage; row 0 = top."""
        return unpremultiply(self.read_texture(self.tex[("blur", k)]))

    # ------------------------------------------------------------------ inspection
    read_texture = staticmethod(read_texture)

    def debug_buffers(self) -> dict:
        out = {}
        if "irradiance" not in self.tex:
            return out
        out["irradiance"] = self.read_texture(self.tex["irradiance"])
        out["stretch"] = self.read_texture(self.tex["stretch_0"])
        k = 0
        while ("blur", k) in self.tex:
            out[f"blur_{k + 1}"] = self.blurred(k)
            k += 1
        out["translucency"] = self.read_texture(self.tex["translucency"])
        frame = self.renderer.last_frame
        if frame is not None:
            out["diffuse_texture_space"] = self.combined(frame)
            out["specular"] = self.renderer.side_render(self.name, OutputMode.SPECULAR)
        return out

    def release(self):
        self.release_textures()
        self._nearest.release()
        for v in self.vaos.values():
            v.release()
        self._irradiance_programs.release()
        self._light_programs.release()
        self._inputs.release()
        if self._detail_buffer is not None:
            self._detail_buffer.release()
            self._detail_buffer = None
        for p in (self.p_stretch, self.p_dilate, self.p_down, self.p_trans, self.p_trans_tent,
                  *self._final_programs.values(),
                  self.p_combine, *self._blur_programs.values(), *([self._p_narrow] if self._p_narrow else []),
                  *(self._p_bounce or ()), *self._programs.values(), *([self._p_trans_static] if self._p_trans_static else [])):
            p.release()
