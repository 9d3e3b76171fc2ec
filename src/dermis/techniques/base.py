"""What every technique shares: the frame it draws into and the pass timer.

A technique is a class with a ``name``, built once per Renderer (programs compiled once), whose
``render(frame)`` draws the lit mesh, linear HDR radiance, into ``frame.target`` (a multisampled
float framebuffer, already cleared to the background). Shadow maps, lights, material textures and
the environment are shared through ``frame``, so every technique lights the same scene.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import moderngl
import numpy as np


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
            t0 = time.perf_counter()
            yield
            self.ctx.finish()
            ms = (time.perf_counter() - t0) * 1e3
        self.times_ms[name] = self.times_ms.get(name, 0.0) + ms

    def reset(self):
        self.times_ms = {}


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
    lighting_key: str = ""
    passes_run: list = field(default_factory=list)
    near: float = 0.1
    far: float = 100.0

    @property
    def viewproj(self) -> np.ndarray:
        return self.proj @ self.view


class Technique:
    name = ""
    description = ""

    def __init__(self, renderer):
        self.renderer = renderer
        self.ctx = renderer.ctx

    def render(self, frame: Frame) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def debug_buffers(self) -> dict:
        """Intermediate buffers of the last frame as float32 (H, W, C) arrays, row 0 = top."""
        return {}

    def release(self) -> None:
        pass


def set_profile_uniforms(prog, profile, max_gaussians: int = 8):
    """The uniforms of shaders/common/profile.glsl: the profile's K variances (mm^2) and its weights
    normalised per channel (sum_k w_k = 1), zero-padded to ``max_gaussians``."""
    from dermis.errors import DermisError
    from dermis.gl.resources import set_uniform

    K = profile.k
    if K > max_gaussians:
        raise DermisError(f"profile '{profile.name}' has {K} Gaussians; at most {max_gaussians} are supported")
    weights = np.zeros((max_gaussians, 3), np.float32)
    weights[:K] = profile.normalized().weights
    variances = np.ones(max_gaussians, np.float32)
    variances[:K] = profile.variances_mm2
    set_uniform(prog, "uGaussianCount", K)
    for name, arr in (("uWeights", weights), ("uVariances", variances)):
        if name in prog:  # the compiler may trim an array's unused tail
            prog[name].write(np.ascontiguousarray(arr[: getattr(prog[name], "array_length", 1)]).tobytes())


def draw_mesh(frame: Frame, prog, units: dict | None = None, vao=None):
    """Bind the shared scene state (camera, lights, shadows, material) and draw the mesh
    (with ``frame.gpu.vao(prog)``, or ``vao``: one that adds a technique's own attributes)."""
    from dermis.gl.resources import mat_bytes, set_uniform

    units = units or {}
    if "uViewProj" in prog:
        prog["uViewProj"].write(mat_bytes(frame.viewproj))
    set_uniform(prog, "uCameraPos", tuple(float(x) for x in frame.eye))
    frame.lights.apply(prog)
    frame.shadows.bind(prog, units.get("uShadowAtlas", 0), units.get("uShadowAux", 1))
    frame.gpu.material_uniforms(prog, {"uAlbedoMap": units.get("uAlbedoMap", 2), "uNormalMap": units.get("uNormalMap", 3),
                                       "uSpecularMap": units.get("uSpecularMap", 4)})
    (vao or frame.gpu.vao(prog)).render(moderngl.TRIANGLES)
