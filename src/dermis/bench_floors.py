"""The floors of ``dermis bench``: what each kind of pass costs at the least on this machine.

A technique's pass time alone says little (llvmpipe and an NVIDIA GPU differ by 1000x); its ratio
to the cheapest pass of the same shape, measured in the same run, says how much of the time is
the technique's own work. Each floor does the same memory traffic as the passes it bounds, with
no arithmetic:

- ``copy``: one full-screen pass that copies the irradiance texture (RGBA16F, S x S) texel for
  texel: the floor of one blur pass; a chain of K Gaussians (2K passes) has a floor of 2K copies
  (``copy_screen``, the same at the output size, bounds screen-space blurs);
- ``uv_raster``: the mesh rasterised in its UV layout into an S x S RGBA16F target with a constant
  fragment: the floor of the texture-space irradiance and translucency passes (tsd's irradiance
  pass also dilates its result into the UV gutters, a full-screen pass: its floor adds one copy);
- ``screen_raster``: the mesh rasterised on screen into the frame's multisampled target, depth
  tested, constant fragment: the floor of a technique's final (screen-space) pass;
- ``depth_only``: the mesh into a depth-only target of the shadow tile size, once per shadowed
  light: the floor of the shadow pass.
"""

from __future__ import annotations

import statistics

import moderngl
import numpy as np

from dermis.camera import camera_matrices
from dermis.gl.resources import mat_bytes, set_uniform
from dermis.gl.shaders import program
from dermis.techniques.base import PassTimer


# Why the minimum: a floor is the machine's undisturbed cost of that memory traffic. On a shared
# machine (round 14: 2 cores, other jobs) a floor sample can only be slowed by other load, never sped
# up, and the floors' samples moved 3-5x between runs while the passes moved less (RESULTS "Issue 14, a
# quiet re-measure"), so a median floor made the multiples swing with the load. The minimum of many
# samples taken across the whole run (before and after every technique's frames) is the stable
# denominator; the passes keep their median (their own time under the same load), so a multiple can
# only err high, never be made small by an inflated floor. The spread (median, max) is reported beside,
# and dermis bench also gives each pass's minimum over the same floor (like with like: under a load
# that lasts the whole run the median multiple rises while that one stays; round 15, perf15, measured
# both over alternated runs in benchmarks/RESULTS.md).
def floor_summary(samples_ms: dict) -> dict:
    """{floor: {"min", "median", "max", "n", "spread"}} of each floor's samples (ms); ``spread`` is
    max / min (None where the floor is 0, i.e. no shadowed light)."""
    out = {}
    for name, v in samples_ms.items():
        lo, hi = min(v), max(v)
        out[name] = {"min": lo, "median": statistics.median(v), "max": hi, "n": len(v),
                     "spread": hi / lo if lo > 0 else None}
    return out


def stable_floors(samples_ms: dict) -> dict:
    """The floors ``dermis bench`` divides by: each floor's minimum sample (ms), see floor_summary."""
    return {name: min(v) for name, v in samples_ms.items()}


class FloorSampler:
    """The floors' targets and programs, built once for ``renderer``'s scene, output size, samples
    and shadow tile size; :meth:`sample` times every floor again (``samples_ms[floor]`` grows), so
    the samples can be interleaved with a benchmark's passes. Release with :meth:`release` (or use
    as a context manager).

    Floors (ms per pass): ``copy`` at S x S, ``copy_screen`` at the output size, ``uv_raster``,
    ``uv_raster_half``, ``screen_raster``, ``depth_only`` (all shadowed lights together; 0.0 when
    no light casts shadows)."""

    def __init__(self, renderer, irradiance_size: int | None = None):
        from dermis.gl.resources import LightUniforms

        ctx = self.ctx = renderer.ctx
        scene = renderer.scene
        gpu = renderer.gpu
        S = int(irradiance_size or renderer.irradiance_size)
        self.timer = PassTimer(ctx, True)
        self.timer.cpu = not self.timer.use_queries  # llvmpipe: the CPU-time clock beside the wall clock
        self._made = made = []

        def keep(o):
            made.append(o)
            return o

        fns = {}
        # copy: RGBA16F S x S -> RGBA16F S x S
        p_copy = keep(program(ctx, "common/fullscreen.vert", "bench/copy.frag"))
        vao_copy = keep(ctx.vertex_array(p_copy, []))

        def copy_pass(w, h):
            src = keep(ctx.texture((w, h), 4, dtype="f2"))
            src.write(np.random.default_rng(0).random((h, w, 4)).astype(np.float16).tobytes())
            src.filter = (moderngl.NEAREST, moderngl.NEAREST)  # bench/copy.frag's read, as tsd's chain's
            src.repeat_x = src.repeat_y = False
            fbo = keep(ctx.framebuffer(color_attachments=[keep(ctx.texture((w, h), 4, dtype="f2"))]))

            def run():
                fbo.use()
                fbo.viewport = (0, 0, w, h)
                src.use(0)
                set_uniform(p_copy, "uSource", 0)
                vao_copy.render(moderngl.TRIANGLES, vertices=3)
            return run, fbo

        fns["copy"], fbo_copy = copy_pass(S, S)
        fns["copy_screen"] = copy_pass(*renderer.size)[0]

        # texture-space raster, full and half resolution (translucency runs at half)
        p_uv = keep(program(ctx, "bench/uv_raster.vert", "bench/constant.frag"))
        vao_uv = gpu.vao(p_uv)
        half = max(S // 2, 1)
        dst_half = keep(ctx.texture((half, half), 4, dtype="f2"))
        fbo_half = keep(ctx.framebuffer(color_attachments=[dst_half]))

        def uv_raster(fbo, n):
            def run():
                fbo.use()
                fbo.viewport = (0, 0, n, n)
                fbo.clear(0.0, 0.0, 0.0, 0.0)
                ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
                vao_uv.render(moderngl.TRIANGLES)
            return run

        fns["uv_raster"] = uv_raster(fbo_copy, S)
        fns["uv_raster_half"] = uv_raster(fbo_half, half)

        # screen raster into a target like the frame's (same size, samples, formats)
        w, h = renderer.size
        samples = renderer.samples if renderer.samples > 1 else 0
        color = keep(ctx.renderbuffer((w, h), 4, samples=samples, dtype="f2"))
        depth = keep(ctx.depth_renderbuffer((w, h), samples=samples))
        fbo_screen = keep(ctx.framebuffer(color_attachments=[color], depth_attachment=depth))
        p_screen = keep(program(ctx, "bench/screen_raster.vert", "bench/constant.frag"))
        lo, hi = scene.bounds()
        view, proj, *_ = camera_matrices(scene.camera, w / h, lo, hi)
        set_uniform(p_screen, "uViewProj", mat_bytes(np.asarray(proj) @ np.asarray(view)))
        vao_screen = gpu.vao(p_screen)

        def screen():
            fbo_screen.use()
            fbo_screen.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.disable(moderngl.CULL_FACE)
            vao_screen.render(moderngl.TRIANGLES)

        fns["screen_raster"] = screen

        # depth-only raster at the shadow tile size, once per shadowed light
        T = renderer.shadows.tile_size
        lights = LightUniforms(scene)
        shadowed = [i for i, L in enumerate(lights.lights) if L.cast_shadows]
        dtex = keep(ctx.depth_texture((T, T)))
        fbo_depth = keep(ctx.framebuffer(depth_attachment=dtex))
        p_depth = keep(program(ctx, "bench/depth_only.vert"))
        vao_depth = gpu.vao(p_depth)

        def depth_only():
            fbo_depth.use()
            fbo_depth.clear(depth=1.0)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.disable(moderngl.CULL_FACE)
            for i in shadowed:
                set_uniform(p_depth, "uViewProj", mat_bytes(lights.viewproj[i]))
                vao_depth.render(moderngl.TRIANGLES)

        fns["depth_only"] = depth_only if shadowed else None
        self._fns = fns
        self.samples_ms = {name: [] for name in fns}
        self.samples_cpu_ms = {name: [] for name in fns}  # on llvmpipe only (dermis.gl.context.cpu_busy_ns)
        for fn in fns.values():  # warm-up: shader compile, first allocation (not a sample)
            if fn is not None:
                fn()
        ctx.enable(moderngl.DEPTH_TEST)

    def sample(self, repeats: int = 1) -> None:
        """Time every floor ``repeats`` times more (each into ``samples_ms``), leaving depth test on
        as the renderer expects."""
        for _ in range(repeats):
            for name, fn in self._fns.items():
                self.timer.reset()
                if fn is not None:  # None: no shadowed light, a floor of 0
                    with self.timer(name):
                        fn()
                self.samples_ms[name].append(self.timer.times_ms.get(name, 0.0))
                if self.timer.cpu:
                    self.samples_cpu_ms[name].append(self.timer.cpu_times_ms.get(name, 0.0))
        self.ctx.enable(moderngl.DEPTH_TEST)

    def release(self):
        for o in reversed(self._made):
            o.release()
        self._made = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def measure_floors(renderer, irradiance_size: int | None = None, repeats: int = 5) -> dict:
    """Floors in ms for ``renderer``'s scene, output size, samples and shadow tile size: each the
    minimum of ``repeats`` samples (:func:`stable_floors`; keys as :class:`FloorSampler`'s)."""
    with FloorSampler(renderer, irradiance_size) as fs:
        fs.sample(repeats)
        return stable_floors(fs.samples_ms)


def _higher_orders() -> int:
    """The bounce light's orders past the one bounce (dermis.geometry.interreflection.BOUNCE_ORDERS - 1)."""
    from dermis.geometry.interreflection import BOUNCE_ORDERS

    return max(int(BOUNCE_ORDERS) - 1, 0)


# Which floor bounds each pass of each technique, and how many floor units the pass holds at
# least. Blur chains: two passes (U, V) per Gaussian of the profile, each at least one copy.
def pass_floor(pass_name: str, floors: dict, gaussians: int) -> float | None:
    if pass_name == "shadow":
        return floors["depth_only"] or None
    # the UV-space raster, then the dilation into the gutters (one copy). Since round 16 the lights are
    # added by a full-screen pass over the inputs (dermis.gl.irradiance_inputs) in place of the raster;
    # the floor is left as rounds 9-15 measured against
    if pass_name == "tsd_irradiance":
        return floors["uv_raster"] + floors["copy"]
    if pass_name == "tsd_irradiance_inputs":  # one UV raster into 6 targets, once per content
        return floors["uv_raster"]
    if pass_name == "ssss_irradiance":
        return floors["screen_raster"]
    if pass_name == "tsd_translucency":
        return floors["uv_raster_half"]
    # the baked transfer: its points' gather (a few taps each) and one full-screen add over the
    # translucency target (half the irradiance's size): at least one half-resolution raster
    if pass_name == "tsd_subsurface_transfer":
        return floors["uv_raster_half"]
    # one UV-space raster of the mesh (the splat; rho E comes from the irradiance pass since round 10)
    # and one copy for the 2x2 reductions of rho E and the per-vertex gather (a low bound: on the head
    # the gather alone reads 2 texels per ray, 9279 x 128 x 2 = 2.4M, where a 1024^2 copy reads 1M)
    # + the higher bounces (gl/interreflection.py BounceSeries): per order past the first one UV-space
    # raster of rho T one level finer than the gather's (half resolution on the head at 1024)
    if pass_name == "tsd_interreflection":
        return floors["uv_raster"] + floors["copy"] + _higher_orders() * floors["uv_raster_half"]
    # the shared bounce (gl/interreflection.py), per lighting change: rho E at half resolution where the
    # gather reads level 2 (the head at 1024), since round 11 one full-screen pass over its texture-space
    # inputs (cheaper than a UV raster) plus the reductions and gather; the floor is left one UV-space
    # raster at that size, as rounds 8-10 measured it against
    if pass_name == "interreflection":  # + the higher bounces, as tsd's
        return (1 + _higher_orders()) * floors["uv_raster_half"]
    if pass_name == "interreflection_inputs":  # one UV raster, once per content
        return floors["uv_raster_half"]
    if pass_name == "tsd_blur":
        return 2 * gaussians * floors["copy"]
    if pass_name == "ssss_blur":
        return 2 * gaussians * floors["copy_screen"]
    if pass_name in ("tsd_final", "ssss_final", "lambert", "preintegrated"):
        return floors["screen_raster"]
    return None
