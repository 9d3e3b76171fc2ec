"""The viewer's panel: Dear ImGui (imgui-bundle) drawn with moderngl on the window's context.

:class:`ImguiRenderer` is a port of Dear ImGui's OpenGL 3 backend (imgui_impl_opengl3.cpp) to
moderngl, including the texture protocol of Dear ImGui 1.92 (the backend creates, updates and
destroys the font atlas textures that ``platform_io.textures`` asks for). :class:`GlfwInput` feeds
GLFW's mouse and keyboard events to ImGui. :class:`Panel` draws the controls and reports which
:class:`~dermis.viewer.params.ViewerParams` fields the user changed.
"""

from __future__ import annotations

import ctypes

import moderngl
import numpy as np

from dermis.gl.resources import set_uniform
from dermis.viewer.params import BUFFER_SCALES, ENVIRONMENTS, IRRADIANCE_SIZES, PROFILES, SKIN_COLORS, TONEMAPS

# the panel's first-use place and width in window pixels (the viewer renders the image right of it:
# viewer/app.py view_rect)
PANEL_MARGIN_PX = 6
PANEL_WIDTH_PX = 330

_VERT = """
#version 450 core
uniform mat4 uProjection;
in vec2 in_position;
in vec2 in_uv;
in vec4 in_color;
out vec2 v_uv;
out vec4 v_color;
void main() {
    v_uv = in_uv;
    v_color = in_color;
    gl_Position = uProjection * vec4(in_position, 0.0, 1.0);
}
"""
# ImGui's colours are sRGB-encoded bytes and the window's framebuffer is not an sRGB one:
# writing them unchanged shows them as designed.
_FRAG = """
#version 450 core
uniform sampler2D uTexture;
in vec2 v_uv;
in vec4 v_color;
out vec4 frag_color;
void main() {
    frag_color = v_color * texture(uTexture, v_uv);
}
"""


def _bytes_at(address: int, size: int):
    return (ctypes.c_char * size).from_address(address)


class ImguiRenderer:
    """Draws ImGui's draw data into the default framebuffer of a moderngl context."""

    def __init__(self, ctx):
        from imgui_bundle import imgui

        self.imgui = imgui
        self.ctx = ctx
        self.context = imgui.create_context()
        imgui.set_current_context(self.context)
        io = imgui.get_io()
        io.set_ini_filename("")  # no imgui.ini in the user's folder
        io.backend_flags |= imgui.BackendFlags_.renderer_has_textures
        pio = imgui.get_platform_io()
        max_size = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 4096))
        pio.renderer_texture_max_width = max_size
        pio.renderer_texture_max_height = max_size
        self.prog = ctx.program(vertex_shader=_VERT, fragment_shader=_FRAG)
        self.vbo = ctx.buffer(reserve=64 * 1024, dynamic=True)
        self.ibo = ctx.buffer(reserve=32 * 1024, dynamic=True)
        fmt = "2f 2f 4f1"  # ImDrawVert: pos, uv, colour (4 normalised bytes)
        assert imgui.VERTEX_SIZE == 20, "unexpected ImDrawVert layout"
        self.vao = ctx.vertex_array(self.prog, [(self.vbo, fmt, "in_position", "in_uv", "in_color")], self.ibo,
                                    index_element_size=imgui.INDEX_SIZE)
        self.textures: dict[int, moderngl.Texture] = {}

    # ------------------------------------------------------------------ textures (ImGui 1.92)
    def _update_textures(self):
        imgui = self.imgui
        for tex in imgui.get_platform_io().textures:
            if tex.status != imgui.ImTextureStatus.ok:
                self._update_texture(tex)

    def _update_texture(self, tex):
        imgui = self.imgui
        S = imgui.ImTextureStatus
        if tex.status == S.want_create:
            pixels = tex.get_pixels_array()
            t = self.ctx.texture((tex.width, tex.height), 4, np.ascontiguousarray(pixels).tobytes())
            t.filter = (moderngl.LINEAR, moderngl.LINEAR)
            t.repeat_x = t.repeat_y = False
            self.textures[t.glo] = t
            tex.set_tex_id(t.glo)
            tex.status = S.ok
        elif tex.status == S.want_updates:
            t = self.textures[tex.tex_id]
            pixels = tex.get_pixels_array().reshape(tex.height, tex.width, 4)
            for r in tex.updates:
                block = np.ascontiguousarray(pixels[r.y:r.y + r.h, r.x:r.x + r.w])
                t.write(block.tobytes(), viewport=(r.x, r.y, r.w, r.h))
            tex.status = S.ok
        elif tex.status == S.want_destroy and tex.unused_frames > 0:
            t = self.textures.pop(tex.tex_id, None)
            if t is not None:
                t.release()
            tex.set_tex_id(0)
            tex.status = S.destroyed

    # ------------------------------------------------------------------ drawing
    def render(self, draw_data, fbo, framebuffer_size):
        """Draw ``draw_data`` into ``fbo`` whose size in pixels is ``framebuffer_size``."""
        self._update_textures()
        fb_w, fb_h = framebuffer_size
        dw, dh = draw_data.display_size
        if fb_w <= 0 or fb_h <= 0 or dw <= 0 or dh <= 0:
            return
        sx, sy = fb_w / dw, fb_h / dh
        ox, oy = draw_data.display_pos
        ctx = self.ctx
        fbo.use()
        fbo.viewport = (0, 0, fb_w, fb_h)
        ctx.enable(moderngl.BLEND)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.blend_func = (moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA)
        ctx.blend_equation = moderngl.FUNC_ADD
        L, R, T, B = ox, ox + dw, oy, oy + dh
        proj = np.array([[2 / (R - L), 0, 0, 0], [0, 2 / (T - B), 0, 0], [0, 0, -1, 0],
                         [(R + L) / (L - R), (T + B) / (B - T), 0, 1]], np.float32)  # column-major
        self.prog["uProjection"].write(proj.tobytes())
        set_uniform(self.prog, "uTexture", 0)
        vsize, isize = self.imgui.VERTEX_SIZE, self.imgui.INDEX_SIZE
        for cl in draw_data.cmd_lists:
            nv, ni = cl.vtx_buffer.size() * vsize, cl.idx_buffer.size() * isize
            if nv == 0 or ni == 0:
                continue
            if nv > self.vbo.size:
                self.vbo.orphan(nv * 2)
            if ni > self.ibo.size:
                self.ibo.orphan(ni * 2)
            self.vbo.write(_bytes_at(cl.vtx_buffer.data_address(), nv))
            self.ibo.write(_bytes_at(cl.idx_buffer.data_address(), ni))
            for cmd in cl.cmd_buffer:
                x0, y0 = (cmd.clip_rect.x - ox) * sx, (cmd.clip_rect.y - oy) * sy
                x1, y1 = (cmd.clip_rect.z - ox) * sx, (cmd.clip_rect.w - oy) * sy
                if x1 <= x0 or y1 <= y0:
                    continue
                t = self.textures.get(cmd.tex_ref.get_tex_id())
                if t is None:
                    continue
                t.use(0)
                ctx.scissor = (int(x0), int(fb_h - y1), int(x1 - x0), int(y1 - y0))
                self.vao.render(moderngl.TRIANGLES, vertices=cmd.elem_count, first=cmd.idx_offset)
        ctx.scissor = None
        ctx.disable(moderngl.BLEND)

    def release(self):
        imgui = self.imgui
        imgui.set_current_context(self.context)
        for tex in imgui.get_platform_io().textures:
            t = self.textures.pop(tex.tex_id, None)
            if t is not None:
                t.release()
            tex.set_tex_id(0)
            tex.status = imgui.ImTextureStatus.destroyed
        for t in self.textures.values():
            t.release()
        self.textures = {}
        self.vao.release()
        self.vbo.release()
        self.ibo.release()
        self.prog.release()
        imgui.destroy_context(self.context)


class GlfwInput:
    """Feeds GLFW events to ImGui (mouse, wheel, keys, text)."""

    def __init__(self):
        import glfw
        from imgui_bundle import imgui

        self.imgui, self.glfw = imgui, glfw
        K = imgui.Key
        self.keymap = {glfw.KEY_TAB: K.tab, glfw.KEY_LEFT: K.left_arrow, glfw.KEY_RIGHT: K.right_arrow,
                       glfw.KEY_UP: K.up_arrow, glfw.KEY_DOWN: K.down_arrow, glfw.KEY_HOME: K.home, glfw.KEY_END: K.end,
                       glfw.KEY_DELETE: K.delete, glfw.KEY_BACKSPACE: K.backspace, glfw.KEY_ENTER: K.enter,
                       glfw.KEY_KP_ENTER: K.keypad_enter, glfw.KEY_ESCAPE: K.escape, glfw.KEY_SPACE: K.space,
                       glfw.KEY_MINUS: K.minus, glfw.KEY_PERIOD: K.period,
                       glfw.KEY_LEFT_CONTROL: K.left_ctrl, glfw.KEY_RIGHT_CONTROL: K.right_ctrl,
                       glfw.KEY_LEFT_SHIFT: K.left_shift, glfw.KEY_RIGHT_SHIFT: K.right_shift,
                       glfw.KEY_LEFT_ALT: K.left_alt, glfw.KEY_RIGHT_ALT: K.right_alt}
        for i in range(10):
            self.keymap[glfw.KEY_0 + i] = getattr(K, f"_{i}")
        for c in "abcdefghijklmnopqrstuvwxyz":
            self.keymap[getattr(glfw, f"KEY_{c.upper()}")] = getattr(K, c)

    def mouse_pos(self, x, y):
        self.imgui.get_io().add_mouse_pos_event(float(x), float(y))

    def mouse_button(self, button, action):
        if 0 <= button < 5:
            self.imgui.get_io().add_mouse_button_event(button, action == self.glfw.PRESS)

    def scroll(self, dx, dy):
        self.imgui.get_io().add_mouse_wheel_event(float(dx), float(dy))

    def key(self, key, action, mods):
        if action == self.glfw.REPEAT:
            action = self.glfw.PRESS
        io = self.imgui.get_io()
        K = self.imgui.Key
        io.add_key_event(K.mod_ctrl, bool(mods & self.glfw.MOD_CONTROL))
        io.add_key_event(K.mod_shift, bool(mods & self.glfw.MOD_SHIFT))
        io.add_key_event(K.mod_alt, bool(mods & self.glfw.MOD_ALT))
        k = self.keymap.get(key)
        if k is not None:
            io.add_key_event(k, action == self.glfw.PRESS)

    def char(self, codepoint):
        self.imgui.get_io().add_input_character(int(codepoint))


class Panel:
    """The controls. ``draw(params, status)`` returns {field: new value} for what the user changed,
    and ``actions`` (a set: "screenshot", "reset_camera") for the buttons pressed."""

    def __init__(self, technique_names, light_count: int):
        from imgui_bundle import imgui

        self.imgui = imgui
        self.techniques = list(technique_names)
        self.light_count = light_count
        self.buffer_names = ["final"]
        self.wants_buffer_names = False

    def draw(self, params, status: dict) -> tuple[dict, set]:
        imgui = self.imgui
        changes, actions = {}, set()
        p = params
        display_h = imgui.get_io().display_size.y
        imgui.set_next_window_pos(imgui.ImVec2(PANEL_MARGIN_PX, PANEL_MARGIN_PX), imgui.Cond_.first_use_ever)
        imgui.set_next_window_size_constraints(imgui.ImVec2(240, 60), imgui.ImVec2(600, max(display_h - 12, 60)))
        imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH_PX, 0), imgui.Cond_.first_use_ever)
        imgui.set_next_window_bg_alpha(0.8)
        imgui.begin("dermis")
        imgui.push_item_width(-120)  # room for the labels
        imgui.text(f"frame {status.get('frame_ms', 0):6.1f} ms   render {status.get('render_ms', 0):6.1f} ms")
        fps = 1e3 / max(status.get("frame_ms", 0) or 1e-3, 1e-3)
        if status.get("quality", "full") == "full":
            imgui.text_disabled(f"{fps:5.1f} fps   full quality")
        else:
            imgui.text_disabled(f"{fps:5.1f} fps   interactive ({status.get('scale', 1.0):.2f}x), refining when input stops")
        imgui.text_disabled(f"ran: {', '.join(status.get('passes_run', [])) or '-'}")
        imgui.text_disabled(f"GPU objects: {status.get('gpu_objects', '?')}")

        def combo(label, key, items, value):
            items = list(items)
            idx = items.index(value) if value in items else 0
            ch, i = imgui.combo(label, idx, items)
            if ch and items[i] != value:
                changes[key] = items[i]

        def slider(label, key, value, lo, hi, fmt="%.3f", flags=0):
            ch, v = imgui.slider_float(label, float(value), lo, hi, fmt, flags)
            if ch:
                changes[key] = float(v)

        combo("technique", "technique", self.techniques, p.technique)
        if imgui.collapsing_header("skin profile", imgui.TreeNodeFlags_.default_open):
            combo("profile", "profile", PROFILES, p.profile)
            log = imgui.SliderFlags_.logarithmic
            slider("melanin", "melanin", p.melanin, 0.0, 0.6, "%.4f", log)
            slider("melanin blend", "melanin_blend", p.melanin_blend, 0.0, 1.0)
            slider("haemoglobin", "hemoglobin", p.hemoglobin, 0.0, 0.2, "%.4f", log)
            slider("oxygenation", "oxygenation", p.oxygenation, 0.0, 1.0)
            slider("epidermis mm", "epidermis_mm", p.epidermis_mm, 0.05, 1.0)
            combo("skin colour", "skin_color", SKIN_COLORS, p.skin_color)
            if status.get("profile_busy"):
                imgui.text_colored(imgui.ImVec4(1.0, 0.8, 0.3, 1.0), "computing profile...")
            if status.get("profile_note"):
                imgui.text_wrapped(status["profile_note"])
        if imgui.collapsing_header("material"):
            slider("mix", "mix", p.mix, 0.0, 1.0)
            slider("roughness m", "roughness", p.roughness, 0.05, 1.0)
            slider("rho_s", "rho_s", p.rho_s, 0.0, 1.0)
        if imgui.collapsing_header("light"):
            if self.light_count > 1:
                ch, i = imgui.slider_int("light", p.light_index, 0, self.light_count - 1)
                if ch:
                    changes["light_index"] = int(i)
            ch, col = imgui.color_edit3("colour", list(p.light_color))
            if ch:
                changes["light_color"] = tuple(float(c) for c in col)
            slider("intensity", "light_intensity", p.light_intensity, 0.0, 20.0, "%.2f")
            imgui.text_disabled("right-drag in the view moves this light")
        if imgui.collapsing_header("environment"):
            combo("environment", "environment", ENVIRONMENTS, p.environment)
            if p.environment == "constant":
                ch, col = imgui.color_edit3("env colour", list(p.environment_color))
                if ch:
                    changes["environment_color"] = tuple(float(c) for c in col)
            slider("env intensity", "environment_intensity", p.environment_intensity, 0.0, 10.0, "%.2f")
        if imgui.collapsing_header("output", imgui.TreeNodeFlags_.default_open):
            slider("exposure", "exposure", p.exposure, -6.0, 6.0, "%.2f stops")
            combo("tone map", "tonemap", TONEMAPS, p.tonemap)
            sizes = [str(s) for s in IRRADIANCE_SIZES]
            combo("irradiance", "irradiance_size", sizes, str(p.irradiance_size))
            if "irradiance_size" in changes:
                changes["irradiance_size"] = int(changes["irradiance_size"])
            if status.get("sizes"):  # the sizes in use; "view": chosen from the view (adaptive_resolution)
                irr, shadow, (auto_irr, auto_shadow) = status["sizes"]
                imgui.text_disabled(f"irradiance {irr}{' (view)' if auto_irr else ''}   "
                                    f"shadow {shadow}{' (view)' if auto_shadow else ''}")
        if imgui.collapsing_header("buffer view"):
            opened = imgui.begin_combo("buffer", p.buffer)
            self.wants_buffer_names = opened
            if opened:
                for name in self.buffer_names:
                    sel, _ = imgui.selectable(name, name == p.buffer)
                    if sel and name != p.buffer:
                        changes["buffer"] = name
                imgui.end_combo()
            combo("scale", "buffer_scale", BUFFER_SCALES, p.buffer_scale)
        if imgui.button("screenshot (S)"):
            actions.add("screenshot")
        imgui.same_line()
        if imgui.button("reset camera (R)"):
            actions.add("reset_camera")
        if status.get("message"):
            imgui.text_wrapped(status["message"])
        imgui.text_disabled("drag: orbit  shift/middle-drag: pan  wheel: zoom\nTab: panel  S: screenshot  Esc: quit")
        imgui.pop_item_width()
        imgui.end()
        return changes, actions
