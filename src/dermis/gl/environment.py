"""The GPU copy of the prefiltered environment (dermis.prefiltered_environment).

One RGB32F texture (float32: HDR radiance has no upper bound) whose mip levels are the prefiltered
levels, LINEAR_MIPMAP_LINEAR, repeating in u (the equirect's seam), clamped in v (the poles), read by
``environment_specular()`` of shaders/common/environment.glsl with an explicit lod (uniform
``uEnvSpecular``). A constant environment is one 1 x 1 level without mipmaps: every lod reads the
constant. numpy row 0 (up, +y) is uploaded first and lands at t = 0, so v = theta / pi with no flip.
"""

from __future__ import annotations

import numpy as np


def upload_environment_specular(ctx, levels):
    """An RGB32F texture of ``levels`` ((h_k, w_k, 3) float32, each half the previous): level k
    at mip level k."""
    import moderngl

    base = np.ascontiguousarray(levels[0], np.float32)
    h, w = base.shape[:2]
    tex = ctx.texture((w, h), 3, base.tobytes(), dtype="f4", alignment=4)
    if len(levels) > 1:
        tex.build_mipmaps(0, len(levels) - 1)  # allocates levels 1.. and sets GL_TEXTURE_MAX_LEVEL
        for k, lv in enumerate(levels[1:], start=1):
            lv = np.ascontiguousarray(lv, np.float32)
            tex.write(lv.tobytes(), level=k, alignment=4)
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    else:
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = True
    tex.repeat_y = False
    return tex
