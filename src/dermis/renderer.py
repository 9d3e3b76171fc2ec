"""The Renderer: one GL context, the scene on the GPU, shared shadow maps, every technique.

It keeps GL resources across frames (for interactive and batch use) and only re-runs what changed:
the shadow atlas when lights or geometry change, texture-space passes (in techniques that have
them) when the lighting key changes. ``render`` returns linear float32 (H, W, 3) radiance.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from dermis.camera import camera_matrices
from dermis.errors import DermisError
from dermis.gl.context import create_context, gl_info, is_software
from dermis.gl.resources import GpuScene, LightUniforms
from dermis.gl.shadows import ShadowAtlas
from dermis.techniques import technique_class
from dermis.techniques.base import Frame, PassTimer

MAX_SIZE = 8192


def check_size(size, what="--size") -> tuple[int, int]:
    try:
        w, h = (int(size[0]), int(size[1]))
    except Exception:
        raise DermisError(f"{what}: size must be two integers WxH, got {size!r}") from None
    if w < 1 or h < 1:
        raise DermisError(f"{what}: size {w}x{h} must be at least 1x1")
    if w > MAX_SIZE or h > MAX_SIZE:
        raise DermisError(f"{what}: size {w}x{h} exceeds the limit of {MAX_SIZE}x{MAX_SIZE}")
    return w, h


def _light_geometry(L) -> tuple:
    """What a light's shadow map depends on."""
    return (L.kind, L.direction, L.position, L.spot_angle_deg, L.cast_shadows)


def _light_state(L) -> tuple:
    """Everything about a light that the image depends on."""
    return _light_geometry(L) + (L.color, L.intensity, L.spot_blend, L.shadow_softness, L.shadow_bias)


def _environment_state(env) -> tuple:
    return (env.color, env.intensity, id(env.image))


def _key(*parts) -> str:
    h = hashlib.sha1()
    for p in parts:
        if isinstance(p, np.ndarray):
            h.update(np.ascontiguousarray(p).tobytes())
        else:
            h.update(repr(p).encode())
    return h.hexdigest()


class Renderer:
    """Keeps a context and a scene's GPU state; renders any technique.

    >>> r = Renderer(scene, size=(512, 512))
    >>> img = r.render("tsd")            # float32 (512, 512, 3), linear radiance
    >>> r.stats                          # pass timings in ms, passes that ran
    """

    def __init__(self, scene=None, size=(512, 512), *, device: int | None = None, samples: int = 4,
                 shadow_size: int = 2048, irradiance_size: int = 1024, ctx=None, timing: bool = True):
        self._owns_ctx = ctx is None
        self.ctx = ctx or create_context(device)
        self.info = gl_info(self.ctx)
        cap = 4 if is_software(self.ctx) else self.ctx.max_samples
        self.samples = int(max(0, min(samples, cap)))
        self.size = check_size(size)
        self.irradiance_size = int(irradiance_size)
        self.shadows = ShadowAtlas(self.ctx, shadow_size)
        self.timer = PassTimer(self.ctx, timing)
        self._techniques = {}
        self._targets = None
        self._targets_size = None
        self.scene = None
        self.gpu = None
        self._shadow_key = None
        self._material_key = None
        self._epoch = 0  # bumped by invalidate(): part of the lighting key
        self.stats = {}
        self.last_frame = None
        if scene is not None:
            self.set_scene(scene)

    # ------------------------------------------------------------------ scene state
    def set_scene(self, scene):
        if self.gpu is not None:
            self.gpu.release()
        self.scene = scene
        self.gpu = GpuScene(self.ctx, scene)
        self._shadow_key = None
        self._material_key = self._material_state()
        for t in self._techniques.values():
            if hasattr(t, "scene_changed"):
                t.scene_changed()

    def _material_state(self):
        m = self.scene.material
        return (id(m.albedo), id(m.normal_map), id(m.specular_map), id(m.roughness_map), m.albedo_color,
                m.roughness if m.roughness_map is None else None)

    def lighting_key(self) -> str:
        """Everything the view-independent (texture-space) passes depend on."""
        s = self.scene
        m = s.material
        lights = [_light_state(L) for L in s.lights]
        env = _environment_state(s.environment)
        mat = (self._material_state(), m.normal_strength, m.roughness, m.rho_s, m.specular_map_bias,
               m.specular_map_scale, m.mix)
        return _key(id(s.mesh), s.mm_per_unit, lights, env, mat, s.skin_color, s.profile.variances_mm2, s.profile.weights,
                    self.irradiance_size, self._epoch)

    def invalidate(self):
        """Make the next frame re-run everything cached between frames (shadow maps and the
        view-independent passes), as a frame with moving lights would: for timings that compare
        techniques like for like (dermis compare). Once-per-mesh work (e.g. tsd's stretch map) stays."""
        self._shadow_key = None
        self._epoch += 1

    # ------------------------------------------------------------------ targets
    def _ensure_targets(self, size):
        if self._targets_size == size:
            return
        self._release_targets()
        w, h = size
        ctx = self.ctx
        if self.samples > 1:
            color = ctx.renderbuffer((w, h), 4, samples=self.samples, dtype="f2")
            depth = ctx.depth_renderbuffer((w, h), samples=self.samples)
        else:
            color = ctx.renderbuffer((w, h), 4, dtype="f2")
            depth = ctx.depth_renderbuffer((w, h))
        msaa = ctx.framebuffer(color_attachments=[color], depth_attachment=depth)
        resolved = ctx.texture((w, h), 4, dtype="f4")
        resolve_fbo = ctx.framebuffer(color_attachments=[resolved])
        self._targets = {"color": color, "depth": depth, "fbo": msaa, "resolved": resolved, "resolve_fbo": resolve_fbo,
                         "readback": np.empty((h, w, 4), np.float32)}
        self._targets_size = size

    def _release_targets(self):
        if self._targets:
            for k, o in self._targets.items():
                if k != "readback":
                    o.release()
        self._targets = None
        self._targets_size = None

    def technique(self, name: str):
        if name not in self._techniques:
            self._techniques[name] = technique_class(name)(self)
        return self._techniques[name]

    # ------------------------------------------------------------------ frame
    def _light_uniforms(self, scene):
        """The packed lights, rebuilt only when a light, the mesh or the environment changes (the
        shadow frusta transform every vertex; an HDR environment is projected to SH)."""
        key = _key(id(scene.mesh), [_light_state(L) for L in scene.lights], _environment_state(scene.environment))
        cached = getattr(self, "_lights_cache", None)
        if cached is None or cached[0] != key:
            self._lights_cache = (key, LightUniforms(scene))
        return self._lights_cache[1]

    def render_mode(self, technique: str, output_mode: int):
        """Re-render the last frame's view with a technique's output mode (e.g. 2 = specular only)."""
        f = self.last_frame
        return self.render(technique, size=f.size if f else None, camera=getattr(self, "_last_camera", None),
                           output_mode=output_mode)

    def render(self, technique: str | None = None, size=None, camera=None, *, with_alpha: bool = False,
               output_mode: int = 0):
        """Render one frame; returns linear float32 (H, W, 3) (or (H, W, 4) with coverage alpha)."""
        if self.scene is None:
            raise DermisError("Renderer has no scene: call set_scene(scene) first")
        name = technique or self.scene.technique
        tech = self.technique(name)
        size = check_size(size or self.size)
        self._ensure_targets(size)
        scene = self.scene
        if self._material_state() != self._material_key:
            self.gpu.upload_material()
            self._material_key = self._material_state()
        self.timer.reset()
        t0 = time.perf_counter()
        cam = camera or scene.camera
        if getattr(cam, "fit", False):
            from dermis.framing import fit_camera, head_vertices

            cam = fit_camera(cam, head_vertices(scene.mesh.positions, cam.up), size[0] / size[1])
        lo, hi = scene.bounds()
        view, proj, eye, near, far = camera_matrices(cam, size[0] / size[1], lo, hi)
        lights = self._light_uniforms(scene)
        passes = []
        # the TSM stores distances in mm: the scale is part of what the shadow pass wrote
        shadow_key = _key(id(scene.mesh), scene.mm_per_unit, [_light_geometry(L) for L in scene.lights])
        if shadow_key != self._shadow_key:
            with self.timer("shadow"):
                self.shadows.render(self.gpu, lights, scene)
            self._shadow_key = shadow_key
            passes.append("shadow")
        else:
            self.shadows.update_params(lights)
        t = self._targets
        bg = scene.output.background
        t["fbo"].use()
        t["fbo"].clear(bg[0], bg[1], bg[2], 0.0, depth=1.0)
        frame = Frame(renderer=self, ctx=self.ctx, scene=scene, gpu=self.gpu, lights=lights, shadows=self.shadows,
                      view=view, proj=proj, eye=eye, size=size, target=t["fbo"], timer=self.timer,
                      lighting_key=self.lighting_key(), passes_run=passes, near=near, far=far)
        self._last_camera = camera
        if output_mode:
            tech.render(frame, output_mode=output_mode)
        else:
            tech.render(frame)
        with self.timer("resolve"):
            self.ctx.copy_framebuffer(t["resolve_fbo"], t["fbo"])
            t["resolved"].read_into(t["readback"])
        img = t["readback"][::-1].copy()
        total = (time.perf_counter() - t0) * 1e3
        self.stats = {"technique": name, "size": list(size), "renderer": self.info["renderer"],
                      "passes_ms": dict(self.timer.times_ms), "passes_run": list(frame.passes_run),
                      "frame_ms": total}
        self.last_frame = frame
        return img if with_alpha else np.ascontiguousarray(img[:, :, :3])

    def debug_buffers(self, technique: str | None = None) -> dict:
        """Intermediate buffers of the last frame as float32 (H, W, C) arrays, row 0 = top: the
        shared shadow atlas (depth, and the translucent shadow map: uv, distance to the light in mm,
        coverage) and whatever the technique keeps (tsd: irradiance, stretch, each blur, ...)."""
        from dermis.gl.resources import read_texture

        name = technique or self.scene.technique
        bufs = {}
        sh = self.shadows
        if sh.depth is not None:
            d = np.frombuffer(sh.depth.read(), np.float32).reshape(sh.depth.size[1], sh.depth.size[0])[::-1]
            bufs["shadow_depth"] = np.repeat(d[:, :, None], 3, axis=2).copy()
            bufs["shadow_tsm"] = read_texture(sh.aux)
        bufs.update(self.technique(name).debug_buffers())
        return bufs

    def release(self):
        for t in self._techniques.values():
            t.release()
        self._techniques = {}
        self._release_targets()
        if self.gpu is not None:
            self.gpu.release()
        self.shadows.release()
        if self._owns_ctx:
            self.ctx.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
