"""Separable screen-space subsurface scattering (``ssss``).

Jimenez, Sundstedt & Gutierrez 2009, "Screen-Space Perceptual Rendering of Human Skin" (ACM TAP
6(4)); Jimenez, Zsolnai, Jarabo et al. 2015, "Separable Subsurface Scattering" (CGF 34(6));
transmittance: Jimenez, Whelan, Sundstedt & Gutierrez 2010, "Real-Time Realistic Skin
Translucency" (IEEE CG&A 30(4)).

What it approximates: the same convolution of the irradiance with the diffusion profile
R(r) = sum_k w_k G(v_k, r) as texture-space diffusion, done on the IMAGE instead of the UV layout,
with each pixel's kernel scaled to millimetres by its depth:

  ssss_irradiance  mesh -> non-multisampled RGBA32F of the frame's size: (E + T) * albedo^mix and the
                   view depth in mm (E: lights, soft shadows, ambient, energy conservation, shared
                   with tsd, and the bounce light between skin surfaces, T per vertex (E_b and its
                   higher orders, dermis.gl.interreflection.BounceSeries) from the
                   Renderer's shared pass, dermis.gl.interreflection.SharedBounce, once per lighting
                   change: added before the blurs, which scatter it as tsd's; T: light through thin
                   parts from the shadow map's thickness)
  ssss_blur        horizontal pass: one image per Gaussian (g_k(x) * E); vertical pass:
                   sum_k w_k g_k(y) * (g_k(x) * E) (the horizontal pass's images stored transposed, so
                   that the vertical taps read along rows: half the vertical pass's time on llvmpipe was
                   its column-wise fetches). Exact for a sum of Gaussians, where a single
                   separable kernel (Jimenez 2015's rank-1 kernel) is 15% off for skin's red.
                   A fixed number of taps per side (``taps``), whatever the head's size on screen:
                   one pixel each near the centre, wider cells sampled stratified (one jittered
                   pixel, weighted by the cell's size) in the wide Gaussians' tails.
                   Grain filter (option ``grain_filter``, on): the Gaussians >= 3 px wide are
                   blurred with 1/2 px^2 less variance per axis, summed apart, and a third
                   pass convolves their sum with the 3 x 3 binomial (variance 1/2 px^2 per
                   axis: the variance restored), same-surface pairs only, backing off where
                   rejected taps make real edges (ssss/grain_filter.frag): the jittered
                   cells' grain at sharp light edges halved, the narrow Gaussians untouched.
                   Pixels per mm = size / (2 tan(fov/2) depth_mm); taps follow the surface (weight
                   of the 3-D distance, taps across a depth jump > depth_cutoff_mm rejected, taps
                   whose straight path to the pixel crosses air rejected: creases, as the
                   reference's paths = "tissue"; a rejected tap keeps its weight and brings
                   the pixel's own light, Jimenez 2015's follow-surface rule, ssss/kernel.glsl).
  ssss_final       the mesh into the frame's target: (scattered * albedo^(1-mix) + T_geo) / pi
                   * (1 - rho_s a(N.V, m) / pi) + specular (added after the blur); T_geo: tsd's baked
                   subsurface transfer of thin, curled parts where the mesh has one
                   (dermis.subsurface_transfer; common/subsurface_transfer.glsl at the fragment's
                   texture-space uv, gathered from the shared rho E once per lighting change: the
                   back-lit ear's same-side light round its curls, which no screen blur sees)

Inputs and units: the scene's mm_per_unit, the camera's projection (widths in pixels come from
depth and field of view), the profile's Gaussians (any K <= 8, weights normalised per channel).
Nothing is cached between frames: screen-space results depend on the view.
Known failure modes: light only comes from what the camera sees (none from behind an ear's
rim, none from off-screen; kernels are cut at the frame's edge); across a crease narrower than a
pixel (closed eyelids at a distance) the tissue-path test cannot separate the two sides; when 3.7 sigma of the widest Gaussian exceeds
``taps`` pixels, the outer taps are jittered per pixel: fine noise where the light has detail at the
scale of the cells (the grain filter removes about half of it; what is left sits beside creases and
silhouettes, where the filter backs off); the
horizontal-then-vertical split follows the surface only along the axes (as in Jimenez 2015).
Shaders: shaders/ssss/*; shared: common/skin_irradiance.glsl, common/transmittance.glsl,
common/subsurface_transfer.glsl, common/skin_specular.glsl.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from dermis.errors import DermisError
from dermis.gl.resources import read_texture, set_uniform
from dermis.gl.shaders import program
from dermis.gl.subsurface_transfer import SubsurfaceTransfer
from dermis.gl.thickness import ThicknessTexture
from dermis.techniques.base import Frame, Technique, TranslucentOptions, check_bool, check_float, check_int, draw_mesh, draw_surfaces
from dermis.techniques.shared import (INTERREFLECTION_DEFINE, MAX_GAUSSIANS, LightCountPrograms, OutputMode, Unit, bind_interreflection, bind_sampler,
                                      bind_sampler_array, TISSUE_TAU, casts_translucency, directional_albedo_uniforms,
                                      subsurface_transfer_uniforms,
                                      prepare_interreflection, set_profile_uniforms, surface_detail_uniforms,
                                      translucency_uniforms)

DEPTH_CUTOFF_MM = 5.0  # a tap this much nearer or further than the pixel is another surface
TAPS = 12  # taps (cells) per side of each blur, whatever the head's size on screen (ssss/kernel.glsl)
MAX_TAPS = 64  # the option's bound


def packed_texels(k: int) -> int:
    """RGBA32UI texels per pixel of the horizontal pass (ssss/packing.glsl's SSSS_PACKED): the depth
    (1 uint), the normal, K Gaussians' rgb and the rejected share as halves (3K + 4 halves, two a uint)."""
    return (1 + (3 * k + 5) // 2 + 3) // 4


def unpack_horizontal(textures, k: int) -> list:
    """The horizontal pass's K images (H, W, 3) float32, row 0 = top, from its packed texels
    (stored transposed: pixel (x, y) at texel (y, x), ssss/blur_horizontal.frag)."""
    h, w = textures[0].size  # the packed texture is H texels wide and W high
    u = np.concatenate([np.frombuffer(t.read(), np.uint32).reshape(w, h, 4) for t in textures], axis=2)
    u = u.transpose(1, 0, 2)[::-1]
    halves = np.ascontiguousarray(u[:, :, 1:1 + (3 * k + 5) // 2]).view(np.float16).astype(np.float32)
    # the widest first: Gaussian i's rgb at halves 4 + 3 (K - 1 - i) .. + 3 (ssss/packing.glsl)
    return [halves[:, :, 4 + 3 * (k - 1 - i):7 + 3 * (k - 1 - i)].copy() for i in range(k)]


def tap_cells(last_px: int, taps: int) -> np.ndarray:
    """First pixel of each of the ``taps`` cells of a side and one past the last: the twin of
    ssss/kernel.glsl's ssss_cell_start. ``last_px``: the last pixel with weight,
    ceil(3.717 sigma_max ppm). Cells with no pixel (start > last_px) are dropped."""
    j = np.arange(taps + 1)
    if last_px <= taps:
        starts = j + 1
    else:
        starts = np.maximum(j + 1, np.floor(np.exp2(np.log2(last_px + 1.0) * j / taps) + 0.5).astype(int))
    starts = np.minimum(starts, last_px + 1)
    return np.unique(starts)


def view_z_row(view: np.ndarray) -> tuple:
    """Third row of the view matrix: view-space z = row . (P, 1) (negative in front)."""
    return tuple(float(x) for x in np.asarray(view, np.float64)[2])


@dataclass(frozen=True)
class SsssOptions(TranslucentOptions):
    taps: int = TAPS  # taps (cells) per side of each blur: the blur's cost, fixed (ssss/kernel.glsl)
    depth_cutoff_mm: float = DEPTH_CUTOFF_MM  # taps across a larger depth jump are rejected
    follow_surface: bool = True  # weight taps by the 3-D distance and reject depth jumps
    tissue_paths: bool = True  # light reaches taps only through the tissue: round concave bends, not across creases
    surface_measure: bool = False  # weigh taps by the surface each pixel holds (ds/dx; ssss/kernel.glsl: off, why)
    grain_filter: bool = True  # the wide Gaussians' jitter noise through a variance-compensated 3 x 3 binomial (ssss/kernel.glsl)

    def validate(self, technique: str) -> None:
        super().validate(technique)
        check_int(f"{technique}: taps", self.taps, 1, MAX_TAPS)
        check_float(f"{technique}: depth_cutoff_mm", self.depth_cutoff_mm)
        check_bool(f"{technique}: follow_surface", self.follow_surface)
        check_bool(f"{technique}: tissue_paths", self.tissue_paths)
        check_bool(f"{technique}: surface_measure", self.surface_measure)
        check_bool(f"{technique}: grain_filter", self.grain_filter)


class ScreenSpaceSSS(Technique):
    name = "ssss"
    description = "separable screen-space SSS (Jimenez et al. 2009/2015): per-Gaussian depth-aware blurs of the image"
    Options = SsssOptions

    def __init__(self, renderer, **options):
        super().__init__(renderer, **options)
        # the final pass per light count, its specular's light loop unrolled (LightCountPrograms), as tsd's
        # final pass (round 23, final23/unroll23); the scene's count compiled now, not on the first frame
        self.p_finals = LightCountPrograms(self.ctx, "common/mesh.vert", "ssss/final.frag").compile_for(renderer.scene)
        self._programs = {}  # (K, taps) -> the passes that loop over the profile, compiled for exactly K Gaussians and taps
        self.p_irradiance = None  # when set (benchmarks and tests swap shaders in), drawn instead of pass 1's own
        self.p_final = None  # likewise for the final pass (tests: the loop over uLightCount), instead of p_finals
        self.vaos = {}
        self.tex = {}
        self._targets_key = None
        self.thickness = ThicknessTexture(self.ctx, filtered=True)  # thickness behind each texel (common/transmittance.glsl)
        self.transfer = SubsurfaceTransfer(self.ctx)  # the baked subsurface transfer, read by the final pass
        renderer.interreflection  # the shared one bounce: made with the first technique that reads it

    # ------------------------------------------------------------------ resources
    def _profile_programs(self, k: int):
        """(irradiance, horizontal, vertical, irradiance with the bounce, grain filter or None)
        programs for a K-Gaussian profile, the irradiance ones as LightCountPrograms (called with the
        light count and lights). Compiled with MAX_GAUSSIANS = K, SSSS_TAPS = the taps option (the loops over
        Gaussians and taps unroll), SSSS_GRAIN_FILTER = the grain_filter option and SSSS_SURFACE_MEASURE =
        surface_measure (with follow_surface)."""
        if k > MAX_GAUSSIANS:
            raise DermisError(f"profile has {k} Gaussians; ssss supports at most {MAX_GAUSSIANS}")
        grain = bool(self.options.grain_filter)
        measure = bool(self.options.surface_measure and self.options.follow_surface)
        key = (k, self.options.taps, grain, measure)
        if key not in self._programs:
            # SSSS_SURFACE_MEASURE compiled in: llvmpipe would run the measure's sqrt and division per tap
            # even when a uniform turns it off (ssss/kernel.glsl ssss_measure)
            ctx, defines = self.ctx, {"MAX_GAUSSIANS": k, "SSSS_TAPS": self.options.taps, "SSSS_GRAIN_FILTER": int(grain),
                                      "SSSS_SURFACE_MEASURE": int(measure)}
            # the irradiance pass per light count, its lights unrolled (LightCountPrograms), and per light
            # signature (the kinds and shadow kernels as constants: the same floats; round 24, sig24)
            progs = (LightCountPrograms(ctx, "common/mesh.vert", "ssss/irradiance.frag", defines, signature=True),
                     program(ctx, "common/fullscreen.vert", "ssss/blur_horizontal.frag", defines),
                     program(ctx, "common/fullscreen.vert", "ssss/blur_vertical.frag", defines),
                     # pass 1 with the shared one bounce added to its irradiance (common/interreflection.glsl)
                     LightCountPrograms(ctx, "common/mesh.vert", "ssss/irradiance.frag", {**defines, INTERREFLECTION_DEFINE: 1},
                                        signature=True),
                     program(ctx, "common/fullscreen.vert", "ssss/grain_filter.frag", defines) if grain else None)
            for p in (progs[1], progs[2], progs[4]):
                if p is not None:
                    self.vaos[p] = ctx.vertex_array(p, [])
            self._programs[key] = progs
        return self._programs[key]

    def _ensure_targets(self, size, k, grain: bool):
        if self._targets_key == (size, k, grain):
            return
        self._release_targets()
        ctx = self.ctx

        def tex(dtype, tex_size=size):
            t = ctx.texture(tex_size, 4, dtype=dtype)
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
            return t

        irradiance = tex("f4")  # a = depth in mm: needs float32 (half: 0.25 mm steps at 500 mm)
        view_normal = tex("f2")  # the geometric normal in view space: the blurs' tissue-path test
        depth = ctx.depth_renderbuffer(size)
        # the horizontal pass's result (ssss/packing.glsl), transposed: H x W, pixel (x, y) at texel (y, x), so that
        # the vertical pass's taps read along rows (ssss/blur_horizontal.frag)
        packed = [tex("u4", (size[1], size[0])) for _ in range(packed_texels(k))]
        scattered = tex("f4")
        self.tex = {"irradiance": irradiance, "view_normal": view_normal, "depth": depth, "packed": packed,
                    "scattered": scattered,
                    "fbo_irradiance": ctx.framebuffer(color_attachments=[irradiance, view_normal], depth_attachment=depth),
                    "fbo_horizontal": ctx.framebuffer(color_attachments=packed)}
        if grain:  # the vertical pass writes the narrow and the wide Gaussians apart; the filter pass sums them
            narrow, wide = tex("f4"), tex("f4")  # wide: a = mask + rejected share / 2 (ssss/blur_vertical.frag)
            self.tex.update({"narrow": narrow, "wide": wide,
                             "fbo_vertical": ctx.framebuffer(color_attachments=[narrow, wide]),
                             "fbo_grain": ctx.framebuffer(color_attachments=[scattered])})
        else:
            self.tex["fbo_vertical"] = ctx.framebuffer(color_attachments=[scattered])
        self._targets_key = (size, k, grain)

    def _release_targets(self):
        for key in ("fbo_irradiance", "fbo_horizontal", "fbo_vertical", "fbo_grain", "irradiance", "view_normal", "depth",
                    "scattered", "narrow", "wide"):
            if key in self.tex:
                self.tex[key].release()
        for t in self.tex.get("packed", []):
            t.release()
        self.tex = {}
        self._targets_key = None

    # ------------------------------------------------------------------ passes
    def _kernel_uniforms(self, prog, frame: Frame, axis: int):
        size = frame.size
        set_profile_uniforms(prog, frame.scene.profile, frame.scene.profile.k)
        # pixels per mm at a view depth of 1 mm along this axis: size / 2 * P[axis][axis]
        set_uniform(prog, "uPixelsPerMmAtUnitDepth", float(0.5 * size[axis] * frame.proj[axis, axis]))
        set_uniform(prog, "uDirection", (1, 0) if axis == 0 else (0, 1))
        set_uniform(prog, "uDepthCutoffMm", float(self.options.depth_cutoff_mm) if self.options.follow_surface else 1e30)
        set_uniform(prog, "uFollowSurface", 1.0 if self.options.follow_surface else 0.0)
        set_uniform(prog, "uPixelsPerMmXY", (float(0.5 * size[0] * frame.proj[0, 0]), float(0.5 * size[1] * frame.proj[1, 1])))
        tissue = self.options.tissue_paths and self.options.follow_surface  # ignoring depth ignores creases too
        set_uniform(prog, "uTissueTau", float(TISSUE_TAU) if tissue else 2.0)
        set_uniform(prog, "uSurfaceMeasure", 1.0 if self.options.surface_measure else 0.0)


    def light_programs(self, scene, bounce: bool):
        """The per-count programs (LightCountPrograms) pass 1's light loop is drawn from for
        ``scene`` (its profile's Gaussian count), with or without the shared bounce."""
        p_irradiance, _, _, p_bounce, _ = self._profile_programs(scene.profile.k)
        return p_bounce if bounce else p_irradiance

    def override_light_program(self, prog) -> None:
        """Draw ``prog`` as pass 1 instead of the per-count programs (None: back to them)."""
        self.p_irradiance = prog
    def screen_space(self, frame: Frame, irradiance: np.ndarray | None = None):
        """Passes 1-3: the pre-scatter irradiance and depth, then the two blurs. ``irradiance``
        (H, W, 3), row 0 = top, replaces the rendered light (depth kept): used by the tests."""
        scene = frame.scene
        profile = scene.profile
        _, p_horizontal, p_vertical, _, p_grain = self._profile_programs(profile.k)
        bounce = prepare_interreflection(frame)  # the shared one bounce, rebuilt only on a lighting change
        p_irradiance = (self.p_irradiance if self.p_irradiance is not None
                        else self.light_programs(scene, bounce)(frame.lights.count, frame.lights.lights))
        self._ensure_targets(tuple(frame.size), profile.k, p_grain is not None)
        t = self.tex
        with frame.timer("ssss_irradiance"):
            fbo = t["fbo_irradiance"]
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            self.ctx.enable(moderngl.DEPTH_TEST)
            self.ctx.disable(moderngl.CULL_FACE)
            prog = p_irradiance
            set_uniform(prog, "uViewZ", view_z_row(frame.view))
            set_uniform(prog, "uViewRotation",  # mat3, column-major
                        np.ascontiguousarray(np.asarray(frame.view, np.float32)[:3, :3].T).tobytes())
            set_profile_uniforms(prog, profile, profile.k)
            directional_albedo_uniforms(prog, scene)
            translucency_uniforms(prog, self.options.translucency and casts_translucency(scene), self.options.translucency_strength,
                                  scene)
            bind_sampler(prog, "uThicknessMap", self.thickness.get(frame, max(self.renderer.irradiance_size // 2, 1)),
                         Unit.FIRST_FREE)
            bind_sampler(prog, "uFarFaceMap", self.thickness.far_face, Unit.FIRST_FREE + 1)
            if bounce:
                bind_interreflection(frame, prog)
            draw_mesh(frame, prog)
            if irradiance is not None:
                a = self.read_texture(t["irradiance"])
                rgb = np.asarray(irradiance, np.float32)
                if rgb.shape[:2] != a.shape[:2]:
                    raise ValueError(f"irradiance override must be {a.shape[:2]} (H, W), got {rgb.shape[:2]}")
                a[:, :, :3] = rgb[:, :, :3]
                t["irradiance"].write(np.ascontiguousarray(a[::-1]).tobytes())
        frame.passes_run.append("ssss_irradiance")
        self.ctx.disable(moderngl.DEPTH_TEST)
        with frame.timer("ssss_blur"):
            prog = p_horizontal
            self._kernel_uniforms(prog, frame, 0)
            bind_sampler(prog, "uIrradiance", t["irradiance"], Unit.FIRST_FREE)
            bind_sampler(prog, "uViewNormal", t["view_normal"], Unit.FIRST_FREE + 1)
            t["fbo_horizontal"].use()
            self.vaos[prog].render(moderngl.TRIANGLES, vertices=3)
            prog = p_vertical
            self._kernel_uniforms(prog, frame, 1)
            bind_sampler(prog, "uIrradiance", t["irradiance"], Unit.FIRST_FREE)
            bind_sampler(prog, "uViewNormal", t["view_normal"], Unit.FIRST_FREE + 1)
            bind_sampler_array(prog, "uPacked", t["packed"], Unit.FIRST_FREE + 2)
            t["fbo_vertical"].use()
            self.vaos[prog].render(moderngl.TRIANGLES, vertices=3)
            if p_grain is not None:
                prog = p_grain
                self._kernel_uniforms(prog, frame, 1)  # the blurs' same-surface rules (depth cutoff, tissue paths)
                bind_sampler(prog, "uNarrow", t["narrow"], Unit.FIRST_FREE)
                bind_sampler(prog, "uWide", t["wide"], Unit.FIRST_FREE + 1)
                bind_sampler(prog, "uViewNormal", t["view_normal"], Unit.FIRST_FREE + 2)
                bind_sampler(prog, "uIrradiance", t["irradiance"], Unit.FIRST_FREE + 3)
                t["fbo_grain"].use()
                self.vaos[prog].render(moderngl.TRIANGLES, vertices=3)
        frame.passes_run.append("ssss_blur")

    def render(self, frame: Frame, output_mode: int = OutputMode.FULL) -> None:
        self.screen_space(frame)
        prog = self.p_final if self.p_final is not None else self.p_finals(frame.lights.count)
        # the baked transfer of thin, curled parts (gathered only on a lighting change; before the target is bound)
        subsurface_transfer_uniforms(prog, frame, self.transfer, self.options.translucency, Unit.FIRST_FREE + 1)
        with frame.timer("ssss_final"):
            frame.target.use()
            self.ctx.enable(moderngl.DEPTH_TEST)
            self.ctx.disable(moderngl.CULL_FACE)
            set_uniform(prog, "uViewZ", view_z_row(frame.view))
            bind_sampler(prog, "uScattered", self.tex["scattered"], Unit.FIRST_FREE)
            surface_detail_uniforms(prog, frame.scene.material, output_mode)
            draw_mesh(frame, prog)
        frame.passes_run.append("ssss_final")
        draw_surfaces(frame, output_mode)  # the non-skin surfaces, with depth testing

    # ------------------------------------------------------------------ inspection
    read_texture = staticmethod(read_texture)

    def scattered(self) -> np.ndarray:
        """The last frame's scattered light before albedo^(1-mix) / pi: (H, W, 3), row 0 = top."""
        return self.read_texture(self.tex["scattered"])[:, :, :3]

    def debug_buffers(self) -> dict:
        if "irradiance" not in self.tex:
            return {}
        irr = self.read_texture(self.tex["irradiance"])
        out = {"ssss_irradiance": irr[:, :, :3].copy(), "ssss_depth_mm": np.repeat(irr[:, :, 3:4], 3, axis=2)}
        for k, g in enumerate(unpack_horizontal(self.tex["packed"], self.renderer.scene.profile.k)):
            out[f"ssss_horizontal_{k + 1}"] = g
        out["ssss_scattered"] = self.scattered()
        if self.renderer.last_frame is not None:
            out["specular"] = self.renderer.side_render(self.name, OutputMode.SPECULAR)
        return out

    def release(self):
        self._release_targets()
        self.thickness.release()
        self.transfer.release()
        for v in self.vaos.values():
            v.release()
        for progs in self._programs.values():
            for p in progs:
                if p is not None:
                    p.release()
        self.p_finals.release()
