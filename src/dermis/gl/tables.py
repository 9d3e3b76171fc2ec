"""GPU copies of the specular lookup tables of :mod:`dermis.specular`.

What a technique feeds ``shaders/common/brdf.glsl``: two single-channel float textures,
R32F (float32: the Beckmann peak 1/m^2 reaches 400 at m = 0.05 and the tables are small, so there is
no reason to give up precision for R16F), LINEAR min/mag filtering, no mipmaps, CLAMP_TO_EDGE:

* ``"beckmann"``: Beckmann P(N.h, m), 512 x 256 texels; the ``beckmannTex`` argument of
  ``beckmann()``, ``beckmann_lookup()``, ``ks_skin_specular()`` (uniform ``uBeckmannTex``).
* ``"rho_dt"``: specular albedo a(cos, m) for rho_s = 1, 64 x 64 texels; the ``rhoDtTex`` argument
  of ``rho_dt_lookup()`` (uniform ``uRhoDtTex``); diffuse keeps 1 - rho_s * a / pi.

A Renderer uploads them once (``Renderer.specular_tables``) and every technique binds them at
the units of the shading contract (dermis.techniques.shared.bind_specular_tables).

The s axis is the table's x (sqrt(1 - N.h), resp. sqrt(cos)), the t axis the log-spaced roughness;
numpy row 0 is uploaded first, which GL places at t = 0 (the bottom row), so numpy row j is texture
row j with no flip. The texel-centre mapping is in dermis/specular.py and specular_table_coord().
"""

from __future__ import annotations

import numpy as np

from dermis.specular import beckmann_table, rho_dt_table



def _float_table_texture(ctx, table: np.ndarray):
    """An R32F texture of a (rows, cols) float32 array: linear, clamp-to-edge, no mipmaps."""
    import moderngl

    data = np.ascontiguousarray(table, dtype=np.float32)
    rows, cols = data.shape
    texture = ctx.texture((cols, rows), 1, data.tobytes(), dtype="f4", alignment=4)
    texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
    texture.repeat_x = False
    texture.repeat_y = False
    return texture


def upload_specular_tables(ctx) -> dict:
    """Create the two specular tables on ``ctx``: {"beckmann": Texture, "rho_dt": Texture}.

    The tables are built once per process (cached in dermis.specular); the caller owns the textures
    and releases them with the context. Use: ``tables["beckmann"].use(unit)`` and set the sampler
    uniform to ``unit``.
    """
    beckmann, _ = beckmann_table()
    return {
        "beckmann": _float_table_texture(ctx, beckmann),
        "rho_dt": _float_table_texture(ctx, rho_dt_table()),
    }
