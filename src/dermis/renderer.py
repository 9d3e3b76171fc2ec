"""The Renderer: one GL context, the scene on the GPU, shared shadow maps, every technique.

It keeps GL resources across frames (for interactive and batch use) and only re-runs what changed.
What each cached product depends on is declared in one table, dermis.invalidation.PRODUCTS, and
keyed on content (array checksums, values), so a changed, swapped or edited-in-place mesh, texture
or environment is seen on the next frame. ``render`` returns linear float32 (H, W, 3) radiance.
"""

from __future__ import annotations

import time

import numpy as np

from dermis.camera import camera_matrices
from dermis.errors import DermisError
from dermis.framing import framed_camera
from dermis.gl.context import create_context, gl_info, is_software
from dermis.geometry.texture_space import scene_texture_space
from dermis.gl.resources import GpuScene, LightUniforms
from dermis.gl.shadows import ShadowAtlas
from dermis.invalidation import ProductKeys, frame_scope, scene_inputs
from dermis.techniques import technique_class
from dermis.techniques.base import Frame, PassTimer
from dermis.techniques.shared import OutputMode
from dermis.validation import MAX_SIZE, check_render_call, check_rendered, check_renderer_options, check_scene, check_size  # noqa: F401

class Renderer:
    """Keeps a context and a scene's GPU state; renders any technique.

    >>> r = Renderer(scene, size=(512, 512))
    >>> img = r.render("tsd")            # float32 (512, 512, 3), linear radiance
    >>> r.stats                          # pass timings in ms, passes that ran
    """

    def __init__(self, scene=None, size=(512, 512), *, device: int | None = None, samples: int = 4,
                 shadow_size: int | None = 2048, irradiance_size: int | None = 1024, ctx=None, timing: bool = True):
        # None: chosen from the mesh's size on screen at set_scene (dermis.adaptive_resolution)
        self.adaptive_sizes = (irradiance_size is None, shadow_size is None)
        irradiance_size = 1024 if irradiance_size is None else irradiance_size
        shadow_size = 2048 if shadow_size is None else shadow_size
        check_renderer_options(size, samples, shadow_size, irradiance_size, device)
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
        self._target_sets = {}  # size -> targets: the previous size's, kept for reuse
        self.target_sizes_kept = 2  # frame sizes whose render targets are kept (the viewer alternates two)
        self._bounce_orders = None  # Renderer.bounce_orders
        self._specular_tables = None
        self._surface_program = None
        self.program_variants = {}  # id(program) -> (program, its variant): dermis.techniques.shared.shading_program
        self._environment_specular = None  # the prefiltered environment texture (gl/environment.py)
        self._interreflection = None  # the shared one-bounce irradiance (gl/interreflection.py SharedBounce)
        # the interreflection bake's hits on the GPU, one copy for tsd's bounce and the shared one (a 1x1
        # stand-in until the first bounce: the count of live GL objects never changes)
        from dermis.gl.interreflection import InterreflectionHits

        self.interreflection_hits = InterreflectionHits(self.ctx, placeholder=True)
        self.scene = None
        self.gpu = None
        self._built = {}  # product -> the key it was built with (dermis.invalidation.PRODUCTS)
        self._lights = None  # LightUniforms of the key self._built["light_uniforms"]
        self._shadow_params_for = None  # (LightUniforms, tile size) the shadow atlas's parameters were set for
        self._epoch = 0  # bumped by invalidate(): an input of the products that invalidate() re-runs
        self._product_keys = ProductKeys()  # the keys, re-derived only for inputs that changed
        self._last_camera = None
        self.visibility = None  # the last VertexVisibility uploaded (geometry/visibility.py), None when off
        self._texture_space_checked = None  # the mesh object _texture_space_mesh last returned
        self.stats = {}
        self.last_frame = None
        if scene is not None:
            self.set_scene(scene)

    # ------------------------------------------------------------------ scene state
    def set_scene(self, scene):
        check_scene(scene)
        self.scene = scene
        self._built = {}
        self._choose_adaptive_sizes()
        self._texture_space_mesh()
        self._rebuild_gpu_scene()

    def _choose_adaptive_sizes(self):
        """Irradiance and shadow sizes from the mesh's size on screen in this Renderer's frame size,
        for the ones the caller left to the renderer (dermis.adaptive_resolution)."""
        auto_irr, auto_shadow = self.adaptive_sizes
        if not (auto_irr or auto_shadow):
            return
        from dermis.adaptive_resolution import adaptive_sizes

        irr, shadow = adaptive_sizes(self.scene, self.size)
        if auto_irr and irr != self.irradiance_size:
            self.set_irradiance_size(irr)
        if auto_shadow and shadow != self.shadows.tile_size:
            self.set_shadow_size(shadow)

    def _texture_space_mesh(self):
        """Give the scene's mesh the UV set texture space works in: its own when unique, else one
        generated with xatlas (dermis.geometry.texture_space). Checked once per mesh object (the
        check rasterises the layout); a new or edited mesh is then keyed on content as usual."""
        if self.scene.mesh is not self._texture_space_checked:
            self.scene.mesh = scene_texture_space(self.scene, self.irradiance_size)
            self._texture_space_checked = self.scene.mesh

    def _rebuild_gpu_scene(self):
        """A new mesh: new buffers (and material textures) on the GPU; techniques drop what they
        built on the old ones."""
        if self.gpu is not None:
            self.gpu.release()
        self.gpu = GpuScene(self.ctx, self.scene)
        for t in self._techniques.values():
            t.scene_changed()

    @property
    def specular_tables(self) -> dict:
        """The specular tables (dermis.gl.tables), uploaded once per Renderer, shared by every technique."""
        if self._specular_tables is None:
            from dermis.gl.tables import upload_specular_tables

            self._specular_tables = upload_specular_tables(self.ctx)
        return self._specular_tables

    @property
    def surface_program(self):
        """The program of non-skin surfaces (glTF metallic-roughness, techniques.base.draw_surfaces),
        compiled once per Renderer, shared by every technique."""
        if self._surface_program is None:
            from dermis.gl.shaders import program

            self._surface_program = program(self.ctx, "common/mesh.vert", "metallic_roughness/surface.frag")
        return self._surface_program

    @property
    def interreflection(self):
        """The one-bounce irradiance per vertex that ssss, preintegrated and lambert share
        (dermis.gl.interreflection.SharedBounce; built on first use, rebuilt per PRODUCTS
        "interreflection"): read it through dermis.techniques.shared.bind_interreflection."""
        if self._interreflection is None:
            from dermis.gl.interreflection import SharedBounce

            self._interreflection = SharedBounce(self.ctx, self.interreflection_hits)
            self._interreflection.programs.compile_for(self.scene)
        return self._interreflection

    @property
    def environment_specular(self):
        """The scene environment's prefiltered specular texture (dermis.gl.environment), rebuilt
        when the environment changes (PRODUCTS "environment_specular")."""
        return self._environment_specular

    def inputs(self) -> dict:
        """This frame's inputs of every cached product (dermis.invalidation.scene_inputs)."""
        return scene_inputs(self.scene, irradiance_size=self.irradiance_size, epoch=self._epoch)

    def product_keys(self) -> dict:
        """The key of every cached product of dermis.invalidation.PRODUCTS for the current scene.
        Inputs equal to the last call's (compared as values: content keys and numbers) are not
        written out and hashed again (dermis.invalidation.ProductKeys)."""
        with frame_scope():
            return self._product_keys(self.inputs())

    def lighting_key(self) -> str:
        """Everything the view-independent (texture-space) passes depend on."""
        return self.product_keys()["texture_space"]

    @property
    def techniques_built(self) -> tuple:
        """Names of the techniques this Renderer has built (their programs compiled)."""
        return tuple(self._techniques)

    def set_irradiance_size(self, n: int):
        """A new texture-space resolution: the techniques' texture-space targets are freed (re-made
        at the new size on the next frame; the size is an input of every texture-space product,
        dermis.invalidation.PRODUCTS, so they re-run). Render targets and the scene stay."""
        from dermis.validation import check_renderer_options

        check_renderer_options(self.size, self.samples, self.shadows.tile_size, int(n), None)
        self.irradiance_size = int(n)
        for tech in self._techniques.values():
            if hasattr(tech, "release_textures"):
                tech.release_textures()

    def set_shadow_size(self, n: int):
        """A new shadow-map tile size (texels per light): the atlas is re-allocated at the next shadow
        pass. The tile size is no input of dermis.invalidation.scene_inputs (whose source keys the
        Cycles stores), so the frame's cached products that read the shadow maps (the atlas, every
        texture-space pass) are re-run through :meth:`invalidate`."""
        from dermis.validation import check_renderer_options

        check_renderer_options(self.size, self.samples, int(n), self.irradiance_size, None)
        if int(n) != self.shadows.tile_size:
            self.shadows.tile_size = int(n)
            self.invalidate()

    @property
    def bounce_orders(self) -> int | None:
        """Orders of the skin-to-skin bounce light (None: dermis.geometry.interreflection.BOUNCE_ORDERS);
        the viewer's preview renderer takes 1 while a light is dragged. Changing it re-runs the
        passes that hold the bounce light (:meth:`invalidate`)."""
        return self._bounce_orders

    @bounce_orders.setter
    def bounce_orders(self, n: int | None):
        n = None if n is None else int(n)
        if n is not None and n < 1:
            raise DermisError(f"bounce_orders must be >= 1 (or None), got {n}")
        if n != self._bounce_orders:
            self._bounce_orders = n
            self.invalidate()

    def invalidate(self):
        """Make the next frame re-run everything cached between frames (shadow maps and the
        view-independent passes), as a frame with moving lights would: for timings that compare
        techniques like for like (dermis compare). Once-per-mesh work (e.g. tsd's stretch map) stays."""
        self._epoch += 1

    # ------------------------------------------------------------------ targets
    def _ensure_targets(self, size, samples=None):
        """The frame's render targets at ``size`` with ``samples`` (default: the Renderer's). The
        ``target_sizes_kept`` most recent (size, samples) are kept (the viewer alternates between a
        reduced size at 1x while dragging and the full one)."""
        samples = self.samples if samples is None else samples
        size = (tuple(size), int(samples))
        if self._targets_size == size:
            return
        kept = self._target_sets.pop(size, None)
        if self._targets is not None:
            self._target_sets[self._targets_size] = self._targets
        while len(self._target_sets) > max(self.target_sizes_kept - 1, 0):
            old = self._target_sets.pop(next(iter(self._target_sets)))
            self._release_target_set(old)
        if kept is not None:
            self._targets, self._targets_size = kept, size
            return
        (w, h), samples = size
        ctx = self.ctx
        if samples > 1:
            color = ctx.renderbuffer((w, h), 4, samples=samples, dtype="f2")
            depth = ctx.depth_renderbuffer((w, h), samples=samples)
        else:
            color = ctx.renderbuffer((w, h), 4, dtype="f2")
            depth = ctx.depth_renderbuffer((w, h))
        msaa = ctx.framebuffer(color_attachments=[color], depth_attachment=depth)
        resolved = ctx.texture((w, h), 4, dtype="f4")
        resolve_fbo = ctx.framebuffer(color_attachments=[resolved])
        # readback buffers by channel count (3 or 4), made on first use: glReadPixels drops alpha itself
        # (numpy's 3-of-4 copy cost 4x a plain copy: 12 ms at 960x640 on the loaded 2-core machine)
        self._targets = {"color": color, "depth": depth, "fbo": msaa, "resolved": resolved, "resolve_fbo": resolve_fbo,
                         "readback": {}}
        self._targets_size = size

    @staticmethod
    def _release_target_set(targets):
        for k, o in targets.items():
            if k != "readback":
                o.release()

    def _release_targets(self):
        for t in [self._targets, *self._target_sets.values()]:
            if t:
                self._release_target_set(t)
        self._target_sets = {}
        self._targets = None
        self._targets_size = None

    def technique(self, name: str, **options):
        """The technique ``name`` (built once per Renderer), with ``options`` (its Options
        dataclass's fields, validated) changed from what it had; e.g. technique("tsd", multires=False)."""
        if name not in self._techniques:
            self._techniques[name] = technique_class(name)(self)
        tech = self._techniques[name]
        if options:
            tech.configure(**options)
        return tech

    # ------------------------------------------------------------------ frame
    def _stale(self, product: str, keys: dict) -> bool:
        return self._built.get(product) != keys[product]

    def _update_scene_products(self, keys: dict, passes: list):
        """Rebuild the renderer's own cached products whose inputs changed."""
        scene = self.scene
        if self._stale("gpu_mesh", keys):
            if "gpu_mesh" in self._built:  # the first frame's GpuScene was made by set_scene
                self._rebuild_gpu_scene()
            self._built["gpu_mesh"] = keys["gpu_mesh"]
            self._built["material_textures"] = keys["material_textures"]
        # a GpuScene made since the last upload (a new mesh) starts with the open sky's visibility
        if self._stale("environment_visibility", keys) or not self.gpu.visibility_uploaded:
            self._upload_visibility(passes)
            self._built["environment_visibility"] = keys["environment_visibility"]
        if self._stale("material_textures", keys):
            self.gpu.upload_material()
            self._built["material_textures"] = keys["material_textures"]
        if self._stale("environment_specular", keys) or self._environment_specular is None:
            from dermis.gl.environment import upload_environment_specular
            from dermis.prefiltered_environment import environment_specular_layers

            with self.timer("environment_prefilter"):
                layers = environment_specular_layers(scene.environment)
                if self._environment_specular is not None:
                    self._environment_specular.release()
                self._environment_specular = upload_environment_specular(self.ctx, layers)
            self._built["environment_specular"] = keys["environment_specular"]
            passes.append("environment_prefilter")
        # the shadow frusta transform every vertex; an HDR environment is projected to SH
        if self._stale("light_uniforms", keys):
            self._lights = LightUniforms(scene)
            self._built["light_uniforms"] = keys["light_uniforms"]
        if self._stale("shadow_atlas", keys):
            with self.timer("shadow"):
                self.shadows.render(self.gpu, self._lights)
            self._built["shadow_atlas"] = keys["shadow_atlas"]
            passes.append("shadow")
        elif self._shadow_params_for != (self._lights, self.shadows.tile_size):  # else they are as they were
            self.shadows.update_params(self._lights)
        self._shadow_params_for = (self._lights, self.shadows.tile_size)

    def _scene_state(self, keys: dict) -> tuple:
        """What the uniforms of techniques.base.bind_scene come from, as (lights, material): the
        objects holding the derived values (compared by identity: each is replaced when its inputs
        change: LightUniforms per PRODUCTS "light_uniforms", the shadow atlas's textures per size)
        and the material's key (PRODUCTS "material_uniforms")."""
        sh = self.shadows
        lights = (self._lights, sh.tile_size, sh._size, sh.depth)
        material = (keys["material_uniforms"], self.gpu, tuple(self.gpu.textures.values()), self._environment_specular,
                    self.specular_tables["atlas"])
        return lights, material

    def _upload_visibility(self, passes: list):
        """in_visibility: the mesh's baked ambient occlusion and the visible fraction of the
        environment's irradiance (the bake cached per mesh content, in memory and on disk), or
        (1, 1, 1, 1) with [environment] occlusion = false or a black environment (nothing to occlude:
        the same image, no bake)."""
        from dermis.environment import environment_is_black
        from dermis.geometry.visibility import mesh_visibility, open_visibility

        m = self.scene.mesh
        env = self.scene.environment
        if env.occlusion and not environment_is_black(env):
            with self.timer("visibility"):
                vis = mesh_visibility(m)
                # the visible fraction of this environment's irradiance: a lookup per occluded ray
                self.gpu.set_visibility(vis.attribute(self.scene.environment))
            self.visibility = vis
            passes.append("visibility")
        else:
            self.gpu.set_visibility(open_visibility(len(m.positions), m.normals))
            self.visibility = None

    def side_render(self, technique: str, output_mode: int):
        """The last frame's view again with another output mode (e.g. specular only), for debug
        buffers: stats, last_frame and the pass timings are left as the frame left them."""
        f = self.last_frame
        saved = (self.stats, self.last_frame, self._last_camera, dict(self.timer.times_ms))
        try:
            return self.render(technique, size=f.size if f else None, camera=self._last_camera, output_mode=output_mode)
        finally:
            self.stats, self.last_frame, self._last_camera, self.timer.times_ms = saved

    def render(self, technique: str | None = None, size=None, camera=None, *, with_alpha: bool = False,
               output_mode: int = OutputMode.FULL, samples: int | None = None, readback: bool = True):
        """Render one frame; returns linear float32 (H, W, 3) (or (H, W, 4) with coverage alpha).
        ``output_mode`` (dermis.techniques.shared.OutputMode): the full image, or one of its terms.
        ``samples``: MSAA samples of this frame only (default: the Renderer's; at most those), for
        the viewer's reduced frames while dragging. ``readback=False``: the frame is drawn and
        resolved on the GPU and nothing is read back (returns None; :meth:`read_frame` reads it):
        frames back to back without waiting for the GPU, as a viewer that shows them on the GPU."""
        with frame_scope():  # each of the scene's arrays is hashed once per frame
            return self._render(technique, size, camera, with_alpha, output_mode, samples, readback)

    def _render(self, technique, size, camera, with_alpha, output_mode, samples, readback):
        if self.scene is None:
            raise DermisError("Renderer has no scene: call set_scene(scene) first")
        try:
            output_mode = OutputMode(output_mode)
        except ValueError:
            raise DermisError(f"output_mode must be one of {', '.join(f'{int(m)} ({m.name.lower()})' for m in OutputMode)}, "
                              f"got {output_mode!r}") from None
        check_render_call(self.scene, technique, camera)
        name = technique or self.scene.technique
        tech = self.technique(name)
        size = check_size(size or self.size)
        if samples is not None:
            samples = int(max(0, min(int(samples), self.samples)))
        self._ensure_targets(size, samples)
        scene = self.scene
        self.timer.reset()
        t0 = time.perf_counter()
        self._texture_space_mesh()
        keys = self.product_keys()
        passes = []
        self._update_scene_products(keys, passes)
        lights = self._lights
        cam = framed_camera(camera or scene.camera, scene.mesh, size[0] / size[1])
        lo, hi = scene.bounds()
        view, proj, eye, near, far = camera_matrices(cam, size[0] / size[1], lo, hi)
        t = self._targets
        bg = scene.output.background
        t["fbo"].use()
        t["fbo"].clear(bg[0], bg[1], bg[2], 0.0, depth=1.0)
        frame = Frame(renderer=self, ctx=self.ctx, scene=scene, gpu=self.gpu, lights=lights, shadows=self.shadows,
                      view=view, proj=proj, eye=eye, size=size, target=t["fbo"], timer=self.timer,
                      keys=keys, passes_run=passes, near=near, far=far, scene_state=self._scene_state(keys))
        self._last_camera = camera
        tech.render(frame, output_mode=output_mode)
        with self.timer("resolve"):
            self.ctx.copy_framebuffer(t["resolve_fbo"], t["fbo"])
            img = self._read_resolved(with_alpha) if readback else None
        if img is not None:
            check_rendered(img, scene, name)
        total = (time.perf_counter() - t0) * 1e3
        self.stats = {"technique": name, "size": list(size), "renderer": self.info["renderer"],
                      "irradiance_size": self.irradiance_size, "shadow_size": self.shadows.tile_size,
                      "passes_ms": dict(self.timer.times_ms), "passes_run": list(frame.passes_run),
                      "frame_ms": total}
        if self.timer.cpu and self.timer.cpu_times_ms:  # dermis bench on llvmpipe: each pass's CPU-time clock too
            self.stats["passes_cpu_ms"] = dict(self.timer.cpu_times_ms)
        self.last_frame = frame
        return img

    def _read_resolved(self, with_alpha: bool) -> np.ndarray:
        """The resolved frame as float32 (H, W, 3 or 4), row 0 = top: one read, one flipping copy."""
        t = self._targets
        c = 4 if with_alpha else 3
        buf = t["readback"].get(c)
        if buf is None:
            w, h = t["resolved"].size
            buf = t["readback"][c] = np.empty((h, w, c), np.float32)
        t["resolve_fbo"].read_into(buf, components=c, dtype="f4")
        return buf[::-1].copy()

    def read_frame(self, with_alpha: bool = False) -> np.ndarray:
        """The last frame (one rendered with ``readback=False``) read back as :meth:`render` returns it."""
        if self._targets is None or self.last_frame is None:
            raise DermisError("Renderer.read_frame: no frame has been rendered yet")
        img = self._read_resolved(with_alpha)
        check_rendered(img, self.scene, self.stats.get("technique", "?"))
        return img

    def debug_buffers(self, technique: str | None = None) -> dict:
        """Intermediate buffers of the last frame as float32 (H, W, C) arrays, row 0 = top: the
        shared shadow atlas's depth and whatever the technique keeps (tsd: irradiance, stretch, each
        blur, ...)."""
        name = technique or self.scene.technique
        bufs = {}
        sh = self.shadows
        if sh.depth is not None:
            d = np.frombuffer(sh.depth.read(), np.float32).reshape(sh.depth.size[1], sh.depth.size[0])[::-1]
            bufs["shadow_depth"] = np.repeat(d[:, :, None], 3, axis=2).copy()
        bufs.update(self.technique(name).debug_buffers())
        return bufs

    def release(self):
        for t in self._techniques.values():
            t.release()
        self._techniques = {}
        self._release_targets()
        if self.gpu is not None:
            self.gpu.release()
        for t in (self._specular_tables or {}).values():
            t.release()
        self._specular_tables = None
        if self._surface_program is not None:
            self._surface_program.release()
            self._surface_program = None
        for _, variant in self.program_variants.values():
            variant.release()
        self.program_variants = {}
        if self._environment_specular is not None:
            self._environment_specular.release()
            self._environment_specular = None
        if self._interreflection is not None:
            self._interreflection.release()
            self._interreflection = None
        self.interreflection_hits.release()
        self.shadows.release()
        if self._owns_ctx:
            self.ctx.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
