"""The GPU copy of the prefiltered environment (dermis.prefiltered_environment).

One RGB32F 3-D texture (float32: HDR radiance has no upper bound): x, y the equirect, z the
roughness layers; LINEAR filtering in all three (bilinear in a map, linear in log m between
layers), repeating in u (the equirect's seam), clamped in v (the poles) and in z; read by
``environment_specular()`` of shaders/common/environment.glsl (uniform ``uEnvSpecular``). A
constant environment is one 1 x 1 x 1 texel: every lookup reads the constant. numpy row 0 (up,
+y) is uploaded first and lands at t = 0, so v = theta / pi with no flip.
"""

from __future__ import annotations

import numpy as np


def upload_environment_specular(ctx, layers):
    """An RGB32F 3-D texture of ``layers`` ((n, h, w, 3) float32)."""
    import moderngl

    data = np.ascontiguousarray(layers, np.float32)
    n, h, w = data.shape[:3]
    tex = ctx.texture3d((w, h, n), 3, data.tobytes(), dtype="f4", alignment=4)
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = True
    tex.repeat_y = False
    tex.repeat_z = False
    return tex
