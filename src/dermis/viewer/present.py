"""Show a linear HDR image: the output transform (exposure, tone map, sRGB) on the GPU.

The shader (shaders/viewer/present.frag) is the twin of :func:`dermis.output.output_transform`
and is tested against it. Bloom, when a scene asks for it, is applied on the CPU to the linear
image before upload (it is a blur of the whole frame, not a per-pixel curve).
"""

from __future__ import annotations

import moderngl
import numpy as np

from dermis.gl.resources import set_uniform
from dermis.gl.shaders import program

TONEMAP_CODES = {"aces": 0, "linear": 1}


def fit_rect(image_size, area):
    """The largest rectangle of the image's aspect centred in ``area`` = (x, y, w, h), in pixels."""
    iw, ih = image_size
    x, y, w, h = area
    s = min(w / max(iw, 1), h / max(ih, 1))
    fw, fh = max(1, int(round(iw * s))), max(1, int(round(ih * s)))
    return (x + (w - fw) // 2, y + (h - fh) // 2, fw, fh)


class Presenter:
    """Uploads a linear (H, W, 3) image to one reused float texture and draws it transformed."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.prog = program(ctx, "viewer/present.vert", "viewer/present.frag")
        self.vao = ctx.vertex_array(self.prog, [])
        self.texture = None
        self._offscreen = None

    def upload(self, linear_rgb: np.ndarray):
        img = np.ascontiguousarray(np.asarray(linear_rgb, np.float32)[:, :, :3])
        h, w = img.shape[:2]
        if self.texture is None or self.texture.size != (w, h):
            if self.texture is not None:
                self.texture.release()
            self.texture = self.ctx.texture((w, h), 3, dtype="f4")
            self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.texture.repeat_x = self.texture.repeat_y = False
        self.texture.write(img.tobytes())

    def draw(self, fbo, rect, exposure: float = 0.0, tonemap: str = "aces"):
        """Draw the uploaded image into ``rect`` = (x, y, w, h) of ``fbo`` (y from the bottom)."""
        if self.texture is None:
            return
        if tonemap not in TONEMAP_CODES:
            raise ValueError(f"unknown tone map '{tonemap}' (one of {', '.join(TONEMAP_CODES)})")
        ctx = self.ctx
        fbo.use()
        fbo.viewport = tuple(int(v) for v in rect)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        self.texture.use(0)
        set_uniform(self.prog, "uImage", 0)
        set_uniform(self.prog, "uExposureScale", float(2.0 ** float(exposure)))
        set_uniform(self.prog, "uTonemap", TONEMAP_CODES[tonemap])
        self.vao.render(moderngl.TRIANGLES, vertices=3)

    def transform(self, linear_rgb: np.ndarray, exposure: float = 0.0, tonemap: str = "aces") -> np.ndarray:
        """The GPU output transform of an image, read back: (H, W, 3) display values in [0, 1]."""
        self.upload(linear_rgb)
        w, h = self.texture.size
        if self._offscreen is None or self._offscreen[0].size != (w, h):
            self._release_offscreen()
            tex = self.ctx.texture((w, h), 4, dtype="f4")
            self._offscreen = (tex, self.ctx.framebuffer(color_attachments=[tex]))
        tex, fbo = self._offscreen
        self.draw(fbo, (0, 0, w, h), exposure, tonemap)
        out = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(h, w, 4)
        return out[::-1, :, :3].copy()

    def _release_offscreen(self):
        if self._offscreen is not None:
            self._offscreen[1].release()
            self._offscreen[0].release()
            self._offscreen = None

    def release(self):
        self._release_offscreen()
        if self.texture is not None:
            self.texture.release()
            self.texture = None
        self.vao.release()
        self.prog.release()
