"""What every technique shares: the frame it draws into and the pass timer.

A technique is a class with a ``name``, built once per Renderer (programs compiled once), whose
``render(frame)`` draws the lit mesh, linear HDR radiance, into ``frame.target`` (a multisampled
float framebuffer, already cleared to the background). Shadow maps, lights, material textures and
the environment are shared through ``frame``, so every technique lights the same scene.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import moderngl
import numpy as np

from dermis.errors import DermisError
from dermis.gl.context import cpu_busy_ns
from dermis.techniques.shared import OutputMode, bind_environment_specular, bind_specular_tables, shading_program


class PassTimer:
    """Times GL passes: GL_TIME_ELAPSED queries on GPUs; on Mesa's CPU rasteriser (whose timer
    queries are unreliable) wall time around ctx.finish(), which is exact there since the
    "GPU" is the same CPU."""

    def __init__(self, ctx, enabled: bool = True):
        from dermis.gl.context import is_software

        self.ctx = ctx
        self.enabled = enabled
        self.use_queries = not is_software(ctx)
        self.times_ms: dict[str, float] = {}
        self._queries = {}
        # on llvmpipe, with ``cpu`` set: also each pass's CPU time (dermis.gl.context.cpu_busy_ns) in
        # cpu_times_ms, a clock that does not grow while another process holds a core (dermis bench)
        self.cpu = False
        self.cpu_times_ms: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str):
        if not self.enabled:
            yield
            return
        if self.use_queries:
            q = self._queries.get(name)
            if q is None:
                q = self._queries[name] = self.ctx.query(time=True)
            t0 = time.perf_counter()
            with q:
                yield
            ns = q.elapsed
            ms = ns / 1e6 if 0 < ns < 0xFFFFFFFF else (time.perf_counter() - t0) * 1e3
        else:
            self.ctx.finish()
            c0 = cpu_busy_ns() if self.cpu else None
            t0 = time.perf_counter()
            yield
            self.ctx.finish()
            ms = (time.perf_counter() - t0) * 1e3
            if c0 is not None:
                self.cpu_times_ms[name] = self.cpu_times_ms.get(name, 0.0) + (cpu_busy_ns() - c0) / 1e6
        self.times_ms[name] = self.times_ms.get(name, 0.0) + ms

    def reset(self):
        self.times_ms = {}
        self.cpu_times_ms = {}


@dataclass
class Frame:
    renderer: object
    ctx: object
    scene: object
    gpu: object  # GpuScene
    lights: object  # LightUniforms
    shadows: object  # ShadowAtlas
    view: np.ndarray
    proj: np.ndarray
    eye: np.ndarray
    size: tuple
    target: object  # moderngl.Framebuffer (multisampled, RGBA16F + depth)
    timer: PassTimer
    keys: dict = field(default_factory=dict)  # product -> key of its inputs (dermis.invalidation.PRODUCTS)
    passes_run: list = field(default_factory=list)
    near: float = 0.1
    far: float = 100.0
    # (lights, material): each changes whenever what bind_scene writes from it would (the
    # Renderer's; None: always written)
    scene_state: object = None

    @property
    def viewproj(self) -> np.ndarray:
        return self.proj @ self.view

    @property
    def lighting_key(self) -> str:
        """The key of everything the view-independent (texture-space) passes depend on."""
        return self.keys.get("texture_space", "")


# ---------------------------------------------------------------------- options
def check_bool(what: str, value) -> None:
    if not isinstance(value, (bool, np.bool_)):
        raise DermisError(f"{what} must be true or false, got {value!r}")


def check_int(what: str, value, lo: int, hi: int | None = None) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo or (hi is not None and value > hi):
        rng = f"{lo}..{hi}" if hi is not None else f">= {lo}"
        raise DermisError(f"{what} must be an integer {rng}, got {value!r}")


def check_float(what: str, value, lo: float = 0.0) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not math.isfinite(value) or value < lo:
        raise DermisError(f"{what} must be a finite number >= {lo:g}, got {value!r}")


def check_choice(what: str, value, choices) -> None:
    if value not in choices:
        raise DermisError(f"{what} must be one of {', '.join(map(repr, choices))}, got {value!r}")


@dataclass(frozen=True)
class TechniqueOptions:
    """A technique's options: a frozen dataclass whose validate() refuses bad values
    (DermisError naming the option). Set through Renderer.technique(name, **options)."""

    def validate(self, technique: str) -> None:
        pass


@dataclass(frozen=True)
class TranslucentOptions(TechniqueOptions):
    """Options of the techniques that carry light through thin parts (tsd, ssss, preintegrated)."""

    translucency: bool = True  # light through thin parts from the (translucent) shadow maps
    translucency_strength: float = 1.0  # 1 = physical

    def validate(self, technique: str) -> None:
        check_bool(f"{technique}: translucency", self.translucency)
        check_float(f"{technique}: translucency_strength", self.translucency_strength)


@functools.lru_cache(maxsize=None)
def _option_names(options_class) -> frozenset:
    """The fields of a technique's Options dataclass (asked on every attribute a technique sets)."""
    return frozenset(f.name for f in dataclasses.fields(options_class))


class Technique:
    name = ""
    description = ""
    Options = TechniqueOptions

    def __init__(self, renderer, **options):
        self.renderer = renderer
        self.ctx = renderer.ctx
        self.options = self.Options()
        self.options.validate(self.name)
        if options:
            self.configure(**options)

    def configure(self, **options) -> None:
        """Change options (validated as a whole before any is applied); caches keyed on the
        options (e.g. tsd's texture-space passes) re-run on the next frame."""
        names = [f.name for f in dataclasses.fields(self.Options)]
        unknown = sorted(set(options) - set(names))
        if unknown:
            raise DermisError(f"technique '{self.name}': unknown option {', '.join(unknown)} "
                              f"(options: {', '.join(names) or 'none'})")
        new = dataclasses.replace(self.options, **options)
        new.validate(self.name)
        self.options = new

    def __setattr__(self, name, value):
        if name != "options" and name in _option_names(self.Options):
            raise DermisError(f"technique '{self.name}': option {name} is set with "
                              f"Renderer.technique('{self.name}', {name}=...), which validates it")
        super().__setattr__(name, value)

    def render(self, frame: Frame, output_mode: int = OutputMode.FULL) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def scene_changed(self) -> None:
        """The scene's GPU copy was rebuilt (new scene or mesh): drop what was built on it."""

    def debug_buffers(self) -> dict:
        """Intermediate buffers of the last frame as float32 (H, W, C) arrays, row 0 = top."""
        return {}

    def release(self) -> None:
        pass


def bind_scene(frame: Frame, prog):
    """Bind the shared scene state every lighting pass reads: lights, shadow atlas, material, the
    specular tables and the prefiltered environment, each at its unit of the shading contract
    (dermis.techniques.shared). The uniforms are written only when ``frame.scene_state`` differs
    from the one this program last got (dermis.gl.resources.prepared); the textures every time."""
    from dermis.gl.resources import prepared

    if frame.scene_state is None:
        _bind_lights(frame, prog)
        _bind_material(frame, prog)
    else:  # lights and material apart: a frame whose lights moved leaves the material's alone
        lights_state, material_state = frame.scene_state
        prepared(prog, "lights", lights_state, lambda p: _bind_lights(frame, p))
        prepared(prog, "material", material_state, lambda p: _bind_material(frame, p))


def _bind_lights(frame: Frame, prog):
    frame.lights.apply(prog)
    frame.shadows.bind(prog)


def _bind_material(frame: Frame, prog):
    frame.gpu.material_uniforms(prog)
    bind_specular_tables(prog, frame.renderer.specular_tables)
    bind_environment_specular(prog, frame.renderer.environment_specular)


def draw_mesh(frame: Frame, prog, vao=None):
    """Bind the camera and the shared scene state (:func:`bind_scene`) and draw the mesh
    (with ``frame.gpu.vao(prog)``, or ``vao``: one that adds a technique's own attributes)."""
    from dermis.gl.resources import MESH_TRIANGLE_IMAGE, mat_bytes, set_uniform

    set_uniform(prog, "uViewProj", mat_bytes(frame.viewproj))
    set_uniform(prog, "uCameraPos", tuple(float(x) for x in frame.eye))
    bind_scene(frame, prog)
    if prog.get("uTriangleFrames", None) is not None:  # common/mesh_varyings.glsl
        # the angle of one pixel at the image centre (radians): 2 tan(fov / 2) / height, proj[1][1] =
        # 1 / tan(fov / 2) of a perspective projection
        set_uniform(prog, "uPixelRadians", float(2.0 / (abs(frame.proj[1][1]) * frame.size[1])))
        # gl_PrimitiveID of this one draw of the whole index buffer numbers the triangles from 0
        frame.gpu.triangle_frames().bind_to_image(MESH_TRIANGLE_IMAGE, read=True, write=False)
    if vao is None:  # the same pass without pore detail where it cannot show (its own vertex array: as it is)
        prog = shading_program(frame, prog)
    cull = not frame.scene.material.double_sided  # a closed skin: its back faces are hidden (SkinMaterial)
    if cull:
        frame.ctx.enable(moderngl.CULL_FACE)  # front faces counter-clockwise, GL's default
    (vao or frame.gpu.vao(prog)).render(moderngl.TRIANGLES)
    if cull:
        frame.ctx.disable(moderngl.CULL_FACE)  # the techniques' passes expect it off


def draw_surfaces(frame: Frame, output_mode: int = OutputMode.FULL):
    """Draw the scene's non-skin surfaces (glTF metallic-roughness: dermis.gl.surfaces,
    shaders/metallic_roughness/) into ``frame.target`` with depth testing, after a technique's
    skin passes: lit by the same lights, shadowed through the same atlas, never part of any
    scattering pass (texture-space or screen-space), so nothing is blurred across the boundary.
    Single-sided materials' back faces are culled (glTF 2.0 3.9.6)."""
    surfaces = frame.gpu.surfaces
    if not surfaces:
        return
    from dermis.gl.resources import mat_bytes, set_uniform

    prog = frame.renderer.surface_program
    ctx = frame.ctx
    with frame.timer("surfaces"):
        frame.target.use()
        ctx.enable(moderngl.DEPTH_TEST)
        set_uniform(prog, "uViewProj", mat_bytes(frame.viewproj))
        set_uniform(prog, "uCameraPos", tuple(float(x) for x in frame.eye))
        set_uniform(prog, "uMmPerUnit", float(frame.scene.mm_per_unit))
        set_uniform(prog, "uOutputMode", int(output_mode))
        frame.lights.apply(prog)
        frame.shadows.bind(prog)
        bind_environment_specular(prog, frame.renderer.environment_specular)
        for s in surfaces:
            if s.double_sided:
                ctx.disable(moderngl.CULL_FACE)
            else:
                ctx.enable(moderngl.CULL_FACE)
            s.uniforms(prog)
            s.vao(prog).render(moderngl.TRIANGLES)
        ctx.disable(moderngl.CULL_FACE)
    frame.passes_run.append("surfaces")
