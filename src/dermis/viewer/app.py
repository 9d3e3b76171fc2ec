"""The viewer's window and event loop: ``dermis view``.

One GLFW window with an OpenGL 4.5 core context; moderngl wraps that context and the Renderer
draws into it (``Renderer(scene, size, ctx=ctx)``), so there is one context and no copies
between contexts. Each frame: events -> scripted actions -> parameters into the scene -> render
(only the final pass when just the camera moved: texture-space passes are cached on the
renderer's lighting key) -> show the linear image through the GPU output transform -> panel.

Mouse: left-drag orbits, shift+left or middle-drag pans, wheel zooms, right-drag moves the
selected light. Keys: S screenshot, R reset camera, Tab panel on/off, Esc or Q quit.

Texture sizes: the irradiance and shadow sizes the user did not give (``--irradiance-size``,
``--shadow-size``, the panel's irradiance combo) follow the view: at every full-quality frame the
viewer asks dermis.adaptive_resolution for the sizes of the current camera and window, so zooming in
on an ear gets the texels a close-up needs (d'Eon & Luebke 2007, GPU Gems 3, 14.4.1). Not during a
drag: the reduced frames keep the sizes. A change of sizes re-runs every texture-space pass and
bake at the new size (the example head, 1024/2048 -> 2048/4096: ~11 s on llvmpipe), so it is a
refine step of its own: when input stops the full frame is drawn at the sizes in use (the 2 s
goal of issue 14), and the frame after it, with no input between, at the view's sizes.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.viewer.camera_controls import LightOrbit, OrbitCamera
from dermis.viewer.params import SceneEditor, SkinProfileWorker, ViewerParams

NO_DISPLAY_HINT = "run under xvfb-run: xvfb-run -a dermis view ..."
IDLE_WAIT_S = 0.05  # when nothing changes, wait this long for input before redrawing the panel


def check_display():
    """Raise a one-line DermisError when no window system is reachable (Linux/BSD: X11 or Wayland)."""
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
            raise DermisError(f"no display available (DISPLAY is not set); {NO_DISPLAY_HINT}")


def _import_glfw():
    try:
        import glfw
    except ImportError as exc:  # the wheel ships libglfw; a failure here is an install problem
        raise DermisError(f"cannot load GLFW ({exc}); reinstall dermis (pip install glfw)") from None
    return glfw


def _glfw_error(glfw, what: str) -> DermisError:
    code, desc = glfw.get_error()
    detail = desc.decode(errors="replace") if isinstance(desc, bytes) else str(desc or "")
    if code in (getattr(glfw, "PLATFORM_UNAVAILABLE", -1), getattr(glfw, "PLATFORM_ERROR", -1)) or "display" in detail.lower():
        display = os.environ.get("DISPLAY", "")
        return DermisError(f"no display available ({what}: {detail or 'no window system'}; DISPLAY={display!r}); "
                           f"{NO_DISPLAY_HINT}")
    return DermisError(f"{what}: {detail or 'GLFW error ' + str(code)} (an OpenGL 4.5 core driver is needed)")


class Viewer:
    """The interactive viewer. ``run()`` loops until the window closes (or a script ends) and
    returns a report: frames drawn, frame times, screenshots written, GPU object counts."""

    def __init__(self, scene, size=(960, 640), *, irradiance_size: int | None = None, shadow_size: int | None = None,
                 samples: int = 4, script=None, show_gui: bool = True, screenshot_dir=".", title: str | None = None, vsync: bool | None = None,
                 progressive: bool = True, interactive_ms: float = 80.0):
        from dermis.renderer import Renderer, check_size

        check_display()
        self.size = check_size(size)
        self.script = script
        self.scene = scene
        glfw = self.glfw = _import_glfw()
        glfw.ERROR_REPORTING = "ignore"  # errors are read with get_error() and raised as DermisError
        if not glfw.init():
            raise _glfw_error(glfw, "cannot start GLFW")
        try:
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 4)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 5)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.DEPTH_BITS, 0)  # the renderer draws offscreen; the window only shows it
            glfw.window_hint(glfw.SAMPLES, 0)
            self.window = glfw.create_window(self.size[0], self.size[1], title or f"dermis - {scene.name}", None, None)
            if not self.window:
                raise _glfw_error(glfw, "cannot open an OpenGL 4.5 core window")
            glfw.make_context_current(self.window)
            glfw.swap_interval(0 if (script is not None or vsync is False) else 1)
            import moderngl

            try:
                self.ctx = moderngl.create_context(require=450)
            except Exception as exc:
                raise DermisError(f"the window's OpenGL context is not 4.5 core ({str(exc).splitlines()[0]})") from None
            from dermis.viewer.gpu_objects import GpuObjectTracker
            from dermis.viewer.present import Presenter

            self.gpu_objects = GpuObjectTracker(self.ctx).install()
            self.show_gui = show_gui  # view_rect reads it
            self.gui = None
            # None: from the head's size on screen (dermis.adaptive_resolution), re-chosen as the view changes
            self.auto_sizes = [irradiance_size is None, shadow_size is None]
            if irradiance_size is None or shadow_size is None:
                from dermis.adaptive_resolution import adaptive_sizes

                irr, sh = adaptive_sizes(scene, self.view_size())
                irradiance_size = irr if irradiance_size is None else irradiance_size
                shadow_size = sh if shadow_size is None else shadow_size
            self.params = ViewerParams.from_scene(scene, irradiance_size)
            self.params.validate("viewer")
            # no pass timer: the panel shows which passes ran, not their times, and timing a pass
            # costs a GPU round trip (a finish on llvmpipe) per pass
            self.renderer = Renderer(scene, self.view_size(), ctx=self.ctx, samples=samples,
                                     irradiance_size=self.params.irradiance_size, shadow_size=shadow_size,
                                     timing=False)
            self.presenter = Presenter(self.ctx)
            from dermis.viewer.progressive import ProgressiveRenderer

            self.progressive = ProgressiveRenderer(self.renderer, target_ms=interactive_ms, enabled=progressive)
        except BaseException:
            self._terminate()
            raise
        lo, hi = scene.bounds()
        self.scene_center = (np.asarray(lo, np.float64) + hi) / 2
        self.scene_radius = float(np.linalg.norm(np.asarray(hi, np.float64) - lo) / 2)
        from dermis.framing import framed_camera

        vs = self.view_size()
        # the scene's view as `dermis render` frames it ([camera] fit: the head fills the area the image
        # is drawn in: the window, or its part right of the panel)
        self.orbit = OrbitCamera.from_camera(framed_camera(scene.camera, scene.mesh, vs[0] / vs[1]), self.scene_radius)
        self.editor = SceneEditor(scene)
        self.profiles = SkinProfileWorker(scene.profile)
        self._light_orbit = None
        self._light_orbit_index = None
        self.screenshot_dir = Path(screenshot_dir)
        self.panel = None
        self.input = None
        if show_gui:
            self._start_gui()
        self._drag = None  # (mode, last_x, last_y)
        self._want_screenshot = False
        self._message = ""
        self._buffers_cache = (None, {})
        self._profile_note = ""
        self.frames_drawn = 0
        self._idle = False
        self._view_key = None
        self._last_stats = {}
        self.report = {"frames": 0, "frame_ms": [], "render_ms": [], "passes_run": [], "quality": [], "render_size": [],
                       "texture_space": [], "sizes": [], "screenshots": [],
                       "resources": [], "renderer": self.renderer.info.get("renderer")}
        self.last_image = None  # what the window shows, linear (H, W, 3)
        self._install_callbacks()

    # ------------------------------------------------------------------ set-up
    def _start_gui(self):
        from dermis.techniques import technique_names
        from dermis.viewer.gui import GlfwInput, ImguiRenderer, Panel

        self.gui = ImguiRenderer(self.ctx)
        self.input = GlfwInput()
        self.panel = Panel(technique_names(), len(self.scene.lights))

    def framebuffer_size(self):
        w, h = self.glfw.get_framebuffer_size(self.window)
        return max(int(w), 1), max(int(h), 1)

    def view_rect(self) -> tuple[int, int, int, int]:
        """(x, y, w, h) of the framebuffer the image is rendered for and drawn in: right of the panel
        while it is shown, if that leaves at least half the window, else the whole
        window (the panel then lies over the image)."""
        from dermis.viewer.gui import PANEL_MARGIN_PX, PANEL_WIDTH_PX

        fw, fh = self.framebuffer_size()
        ww = max(int(self.glfw.get_window_size(self.window)[0]), 1)
        # issue 12: "the viewer frames the head in the area the panel leaves free"; the panel at its
        # first-use place and width and a margin's gap, window pixels -> framebuffer pixels (HiDPI)
        reserve = int(round((2 * PANEL_MARGIN_PX + PANEL_WIDTH_PX) * fw / ww))
        if self.show_gui and 2 * reserve <= fw:
            return reserve, 0, fw - reserve, fh
        return 0, 0, fw, fh

    def view_size(self) -> tuple[int, int]:
        """The size the image is rendered at (view_rect's), as ``dermis render --size`` would be given."""
        return self.view_rect()[2:]

    def _install_callbacks(self):
        glfw = self.glfw
        glfw.set_cursor_pos_callback(self.window, lambda w, x, y: self.on_cursor(x, y))
        glfw.set_mouse_button_callback(self.window, lambda w, b, a, m: self.on_mouse_button(b, a, m))
        glfw.set_scroll_callback(self.window, lambda w, dx, dy: self.on_scroll(dx, dy))
        glfw.set_key_callback(self.window, lambda w, k, s, a, m: self.on_key(k, a, m))
        glfw.set_char_callback(self.window, lambda w, c: self.input.char(c) if self.input and self.show_gui else None)

    def _gui_wants(self, what: str) -> bool:
        if not (self.gui and self.show_gui):
            return False
        io = self.gui.imgui.get_io()
        return io.want_capture_mouse if what == "mouse" else io.want_capture_keyboard

    # ------------------------------------------------------------------ input (mouse, keys, scripts)
    def on_cursor(self, x, y):
        if self.input and self.show_gui:
            self.input.mouse_pos(x, y)
        if self._drag is not None:
            mode, lx, ly = self._drag
            self._drag = (mode, x, y)
            self.drag(mode, x - lx, y - ly)

    def on_mouse_button(self, button, action, mods):
        glfw = self.glfw
        if self.input and self.show_gui:
            self.input.mouse_button(button, action)
        if action == glfw.RELEASE:
            if self._drag is not None:
                self.progressive.input_released()  # a drag's release ends the input: refine at once
            self._drag = None
            return
        if self._gui_wants("mouse"):
            return
        x, y = glfw.get_cursor_pos(self.window)
        if button == glfw.MOUSE_BUTTON_LEFT:
            mode = "pan" if mods & glfw.MOD_SHIFT else "orbit"
        elif button == glfw.MOUSE_BUTTON_MIDDLE:
            mode = "pan"
        elif button == glfw.MOUSE_BUTTON_RIGHT:
            mode = "light"
        else:
            return
        self._drag = (mode, x, y)

    def on_scroll(self, dx, dy):
        if self.input and self.show_gui:
            self.input.scroll(dx, dy)
        if not self._gui_wants("mouse"):
            self.orbit.zoom(dy)

    def on_key(self, key, action, mods):
        glfw = self.glfw
        if self.input and self.show_gui:
            self.input.key(key, action, mods)
        if action != glfw.PRESS or self._gui_wants("keyboard"):
            return
        if key in (glfw.KEY_ESCAPE, glfw.KEY_Q):
            glfw.set_window_should_close(self.window, True)
        elif key in (glfw.KEY_S, glfw.KEY_F12):
            self._want_screenshot = True
        elif key == glfw.KEY_R:
            self.orbit.reset()
        elif key == glfw.KEY_TAB:
            self.show_gui = not self.show_gui
            if self.show_gui and self.gui is None:
                self._start_gui()

    def drag(self, mode: str, dx: float, dy: float):
        """A mouse drag of (dx, dy) window pixels: "orbit", "pan" or "light"."""
        if mode == "orbit":
            self.orbit.orbit(dx, dy)
        elif mode == "pan":
            self.orbit.pan(dx, dy, self.glfw.get_window_size(self.window)[1])
        elif mode == "light" and self.scene.lights:
            i = min(max(self.params.light_index, 0), len(self.scene.lights) - 1)
            if self._light_orbit is None or self._light_orbit_index != i:
                self._light_orbit = LightOrbit(self.scene_center, self.scene.lights[i], self.scene_radius)
                self._light_orbit_index = i
            self._light_orbit.drag(dx, dy)
            self._light_orbit.apply(self.scene.lights[i])

    def set_params(self, values: dict, source: str = "viewer"):
        """Change parameters as the panel does (checked; an unknown name is a DermisError)."""
        values = dict(values)
        if "profile" in values and values["profile"] in ("fair", "asian", "dark"):
            self.params.apply_preset(values.pop("profile"))
        if "light_index" in values and self.scene.lights:
            i = int(values["light_index"])
            if 0 <= i < len(self.scene.lights):
                L = self.scene.lights[i]
                values.setdefault("light_color", tuple(L.color))
                values.setdefault("light_intensity", float(L.intensity))
        old_irr = self.params.irradiance_size
        self.params.update(values, source)
        if "irradiance_size" in values:
            self.auto_sizes[0] = False  # the user chose it: it no longer follows the view
        if self.params.irradiance_size != old_irr:
            self._set_irradiance_size(self.params.irradiance_size)

    def _set_irradiance_size(self, n: int):
        """A new texture-space resolution: free the techniques' texture-space targets (they are
        re-made at the new size on the next frame; the size is an input of every texture-space
        product, dermis.invalidation.PRODUCTS, so they re-run)."""
        self.renderer.set_irradiance_size(n)
        self._buffers_cache = (None, {})

    def view_sizes(self, fb=None) -> tuple[int, int]:
        """The (irradiance, shadow tile) sizes for the current view (camera and window): adaptive_sizes'
        for those the user left to the viewer, the renderer's own for the others (~0.5 ms on the
        example head: the mesh's layout density is remembered by dermis.adaptive_resolution)."""
        current = (self.renderer.irradiance_size, self.renderer.shadows.tile_size)
        if not any(self.auto_sizes):
            return current
        from dermis.adaptive_resolution import adaptive_sizes

        irr, shadow = adaptive_sizes(self.scene, fb or self.view_size(), camera=self.orbit.camera())
        # a zoom must not ask for an atlas over the GPU's texture limit (an error mid-session)
        shadow = min(shadow, self.renderer.shadows.max_tile_size(len(self.scene.lights)))
        return (int(irr) if self.auto_sizes[0] else current[0], int(shadow) if self.auto_sizes[1] else current[1])

    def choose_sizes(self, fb=None) -> bool:
        """Give the full renderer the sizes of :meth:`view_sizes`; True when one changed (the
        texture-space passes then re-run). Never mid-drag: at the refine step after the full frame
        (frame()) and before a screenshot (refine_now)."""
        irr, shadow = self.view_sizes(fb)
        changed = False
        if self.auto_sizes[0] and irr != self.renderer.irradiance_size:
            self.params.irradiance_size = int(irr)
            self._set_irradiance_size(int(irr))
            changed = True
        if self.auto_sizes[1] and shadow != self.renderer.shadows.tile_size:
            self.renderer.set_shadow_size(int(shadow))
            self._buffers_cache = (None, {})
            changed = True
        return changed

    def _run_actions(self, actions):
        for a in actions:
            if "set" in a:
                self.set_params(a["set"], self.script.source if self.script else "script")
            if "preset" in a:
                self.set_params({"profile": a["preset"]}, self.script.source if self.script else "script")
            if "orbit" in a:
                self.drag("orbit", *a["orbit"])
            if "pan" in a:
                self.drag("pan", *a["pan"])
            if "light_drag" in a:
                self.drag("light", *a["light_drag"])
            if "zoom" in a:
                self.orbit.zoom(a["zoom"])
            if a.get("reset_camera"):
                self.orbit.reset()

    def _run_after_actions(self, actions):
        for a in actions:
            if "screenshot" in a:
                self.save_screenshot(a["screenshot"])
            if "window_screenshot" in a:
                self.save_window_screenshot(a["window_screenshot"])
            if a.get("resources"):
                self.report["resources"].append({"frame": self.frames_drawn - 1, "counts": self.gpu_objects.counts()})
            if a.get("quit"):
                self.glfw.set_window_should_close(self.window, True)

    # ------------------------------------------------------------------ output
    def displayed_output(self) -> np.ndarray:
        """The display-encoded image the window shows (before the panel), as ``dermis render``
        would write it: (H, W, 3) in [0, 1]."""
        from dermis.output import output_transform

        exposure, tonemap = self._display_transform()
        return output_transform(self.last_image, exposure, tonemap)

    def refine_now(self):
        """Replace a reduced (interactive) image, or one at other sizes than the view's (view_sizes),
        by the full frame of the same view."""
        if self.last_image is None or self.params.buffer != "final":
            return
        fb = self.view_size()
        resized = self.choose_sizes(fb)
        if self.progressive.quality == "full" and not resized:
            return
        if resized:  # the frame drawn is the one the new key names: the next frame stays idle
            self._view_key = self._frame_view_key(fb)
        img = self.progressive.render(self.params.technique, fb, self.orbit.camera(), interactive=False)
        if getattr(self.scene.output, "bloom", 0.0) > 0:
            from dermis.output import bloom

            img = bloom(img, self.scene.output.bloom, self.scene.output.bloom_radius)
        self.last_image = img
        self._last_stats = dict(self.progressive.stats)

    def save_screenshot(self, path=None) -> Path:
        from dermis.images import write_png

        if self.last_image is None:
            raise DermisError("no frame to save yet")
        self.refine_now()  # a screenshot is always the full frame
        if path is None:
            self.screenshot_dir.mkdir(parents=True, exist_ok=True)
            path = self.screenshot_dir / time.strftime("dermis-%Y%m%d-%H%M%S.png")
            n = 1
            while path.exists():
                path = path.with_name(time.strftime("dermis-%Y%m%d-%H%M%S") + f"-{n}.png")
                n += 1
        write_png(path, self.displayed_output())
        self.report["screenshots"].append(str(path))
        self._message = f"saved {path}"
        return Path(path)

    def save_window_screenshot(self, path) -> Path:
        """The window as shown, panel included (the front buffer's copy in the back buffer is
        gone after the swap, so this reads what the last frame drew before swapping)."""
        from PIL import Image

        from dermis.images import atomic_write

        arr = self._last_window_pixels
        atomic_write(path, lambda tmp: Image.fromarray(arr).save(tmp, format="PNG"))
        self.report["screenshots"].append(str(path))
        return Path(path)

    def _display_transform(self):
        p = self.params
        if p.buffer != "final" and p.buffer_scale == "auto":
            return 0.0, "linear"
        return p.exposure, p.tonemap

    # ------------------------------------------------------------------ buffers
    def _buffer_image(self, name: str):
        r = self.renderer
        key = (self.params.technique, r.lighting_key(), r.irradiance_size)
        if name == "specular":
            key = key + (self.orbit.state(), self.view_size())
        cached_key, bufs = self._buffers_cache
        if cached_key != key:
            bufs = r.debug_buffers(self.params.technique)  # a side path: the frame's stats stay
            self._buffers_cache = (key, bufs)
        names = ["final"] + sorted(bufs)
        if self.panel is not None:
            self.panel.buffer_names = names
        if name not in bufs:
            return None
        a = np.asarray(bufs[name], np.float32)
        if a.shape[2] == 1:
            a = np.repeat(a, 3, axis=2)
        elif a.shape[2] == 2:
            a = np.concatenate([a, np.zeros_like(a[:, :, :1])], axis=2)
        a = a[:, :, :3]
        if self.params.buffer_scale == "auto":
            finite = a[np.isfinite(a)]
            top = float(np.percentile(np.abs(finite), 99.5)) if finite.size else 1.0
            a = np.nan_to_num(a / (top if top > 0 else 1.0))
        return np.ascontiguousarray(a)

    # ------------------------------------------------------------------ the loop
    def _update_profile(self, wait: bool):
        want = self.params.profile_request()
        if want == self.editor.applied_profile_request:
            return
        res = self.profiles.get(self.params, wait=wait)
        if res is not None:
            self.editor.apply_profile(res)
            self._profile_note = res.note

    def frame(self):
        """Draw one frame (the loop's body; scripts call it through run())."""
        glfw = self.glfw
        scripted = self.script is not None
        if not scripted and self._idle and not self.profiles.busy:
            glfw.wait_events_timeout(IDLE_WAIT_S)  # nothing moved last frame: sleep until input
        else:
            glfw.poll_events()
        t0 = time.perf_counter()
        if scripted:
            self._run_actions(self.script.before(self.frames_drawn))
        self._update_profile(wait=scripted)
        self.editor.apply(self.params)
        fb = self.framebuffer_size()
        area = self.view_rect()
        vs = area[2:]  # the size rendered at: the window, or its part right of the panel
        view_key = self._frame_view_key(vs)
        lighting_key = view_key[-1]
        changed = view_key != self._view_key or self.last_image is None
        # progressive: a reduced frame while input is active, the full frame once it stops (a
        # script's input is its actions: the first frame without any refines)
        refine = not changed and (self.progressive.quality != "full" if scripted else
                                  self.progressive.needs_refine(input_held=self._drag is not None))
        # the sizes of the view (zoomed in or out, a new window size) once the full frame at the sizes
        # in use is shown and no input is held: a refine step of its own (the module's docstring)
        resize = (not changed and not refine and self.progressive.quality == "full" and self._drag is None
                  and self.params.buffer == "final" and self.last_image is not None
                  and self.view_sizes(vs) != (self.renderer.irradiance_size, self.renderer.shadows.tile_size))
        self._idle = not changed and not refine and not resize
        if self._idle:  # the same view: show the last image again (the panel may still change)
            stats = dict(self._last_stats, passes_run=[])
            shown = self.last_image
        else:
            interactive = changed and self.last_image is not None and self.params.buffer == "final"
            if resize and self.choose_sizes(vs):
                view_key = self._frame_view_key(vs)  # new sizes: a new lighting key (and params)
                lighting_key = view_key[-1]
            if scripted and self.script.scales:  # the script's scale for this frame, not the frame time's
                self.progressive.pin_scale(self.script.scales[self.frames_drawn % len(self.script.scales)])
            img = self.progressive.render(self.params.technique, vs, self.orbit.camera(), interactive=interactive,
                                          lighting_key=lighting_key)
            stats = dict(self.progressive.stats)
            shown = img
            if self.params.buffer != "final":
                b = self._buffer_image(self.params.buffer)
                if b is not None:
                    shown = b
                else:
                    self._message = f"no buffer '{self.params.buffer}' in technique {self.params.technique}"
            elif getattr(self.scene.output, "bloom", 0.0) > 0:
                from dermis.output import bloom

                shown = bloom(img, self.scene.output.bloom, self.scene.output.bloom_radius)
            self.last_image = shown
            self._view_key = view_key
            self._last_stats = stats
        # show it
        screen = self.ctx.screen
        screen.use()
        screen.viewport = (0, 0, *fb)
        self.ctx.scissor = None
        screen.clear(0.08, 0.08, 0.09, 1.0)
        from dermis.viewer.present import fit_rect

        exposure, tonemap = self._display_transform()
        if not self._idle:
            self.presenter.upload(shown)
        self.presenter.draw(screen, fit_rect((shown.shape[1], shown.shape[0]), area), exposure, tonemap)
        frame_ms = (time.perf_counter() - t0) * 1e3
        if self.gui is not None and self.show_gui:
            self._draw_gui(fb, stats, frame_ms)
        wants_window_shot = scripted and any("window_screenshot" in a for a in self.script.after(self.frames_drawn))
        if wants_window_shot:
            data = screen.read(viewport=(0, 0, *fb), components=3, alignment=1)
            self._last_window_pixels = np.frombuffer(data, np.uint8).reshape(fb[1], fb[0], 3)[::-1].copy()
        glfw.swap_buffers(self.window)
        self.frames_drawn += 1
        frame_ms = (time.perf_counter() - t0) * 1e3
        self.report["frames"] = self.frames_drawn
        self.report["frame_ms"].append(round(frame_ms, 3))
        self.report["render_ms"].append(round(float(stats.get("frame_ms", 0.0)), 3))
        self.report["passes_run"].append(stats.get("passes_run", []))
        self.report["quality"].append("idle" if self._idle else stats.get("quality", "full"))
        self.report["render_size"].append(list(stats.get("size", vs)))
        self.report["texture_space"].append(stats.get("renderer", "full"))
        self.report["sizes"].append([int(stats.get("irradiance_size", 0)), int(stats.get("shadow_size", 0))])
        if not self._idle:
            self._last_frame_ms = frame_ms
        if self._want_screenshot:
            self._want_screenshot = False
            self.save_screenshot()
        if scripted:
            self._run_after_actions(self.script.after(self.frames_drawn - 1))
        if not (self.gui and self.show_gui) and self.frames_drawn % 15 == 1:
            glfw.set_window_title(self.window, f"dermis - {self.params.technique} - {frame_ms:.1f} ms/frame "
                                               f"(render {stats.get('frame_ms', 0):.1f} ms)")

    def _frame_view_key(self, size) -> tuple:
        """What a frame's image depends on: camera, parameters, the size rendered at (view_size) and
        the renderer's lighting key (last)."""
        return (self.orbit.state(), dataclasses.astuple(self.params), size, self.renderer.lighting_key())

    def _draw_gui(self, fb, stats, frame_ms):
        imgui = self.gui.imgui
        imgui.set_current_context(self.gui.context)
        io = imgui.get_io()
        ww, wh = self.glfw.get_window_size(self.window)
        io.display_size = imgui.ImVec2(max(ww, 1), max(wh, 1))
        io.display_framebuffer_scale = imgui.ImVec2(fb[0] / max(ww, 1), fb[1] / max(wh, 1))
        now = time.perf_counter()
        io.delta_time = max(now - getattr(self, "_gui_time", now - 1 / 60), 1e-4)
        self._gui_time = now
        status = {"frame_ms": getattr(self, "_last_frame_ms", frame_ms), "render_ms": stats.get("frame_ms", 0.0),
                  "quality": stats.get("quality", "full"), "scale": stats.get("scale", 1.0),
                  "passes_run": stats.get("passes_run", []), "gpu_objects": self.gpu_objects.total(),
                  "sizes": (self.renderer.irradiance_size, self.renderer.shadows.tile_size, tuple(self.auto_sizes)),
                  "profile_busy": self.profiles.busy, "profile_note": self._profile_note, "message": self._message}
        if not getattr(self, "_gui_laid_out", False):
            # ImGui hides a window for the frame in which it first auto-fits its size (the panel's
            # first-use height is 0: fit to its content), so frame 0 would show no panel: lay the
            # panel out once unseen, its input ignored, then draw it.
            self._gui_laid_out = True
            imgui.new_frame()
            self.panel.draw(self.params, status)
            imgui.render()
        imgui.new_frame()
        changes, actions = self.panel.draw(self.params, status)
        imgui.render()
        self.gui.render(imgui.get_draw_data(), self.ctx.screen, fb)
        if self.panel.wants_buffer_names and len(self.panel.buffer_names) <= 1:
            self._buffer_image("")  # fills the panel's list of buffers
        if changes:
            try:
                self.set_params(changes, "panel")
            except DermisError as exc:
                self._message = str(exc)
        if "screenshot" in actions:
            self._want_screenshot = True
        if "reset_camera" in actions:
            self.orbit.reset()

    def run(self) -> dict:
        try:
            while not self.glfw.window_should_close(self.window):
                if self.script is not None and self.script.done(self.frames_drawn):
                    break
                self.frame()
        finally:
            if self.script is not None and self.script.report is not None:
                from dermis.cli import write_json_atomic

                write_json_atomic(self.script.report, self.report)
        return self.report

    # ------------------------------------------------------------------ teardown
    def _terminate(self):
        try:
            self.glfw.terminate()
        except Exception:
            pass

    def close(self):
        if getattr(self, "window", None) is None:
            return
        self.profiles.close()
        self.glfw.make_context_current(self.window)
        if self.gui is not None:
            self.gui.release()
        self.presenter.release()
        self.progressive.release()
        self.renderer.release()
        self.ctx.release()
        self.glfw.destroy_window(self.window)
        self.window = None
        self._terminate()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def view(scene, size=(960, 640), **options) -> dict:
    """Open the viewer on ``scene`` and run it until closed; returns the session report."""
    with Viewer(scene, size, **options) as v:
        return v.run()
