"""GPU copies of the specular lookup tables of :mod:`dermis.specular`.

What a technique feeds ``shaders/common/brdf.glsl``: ONE single-channel float texture holding both
tables side by side (dermis.specular.TABLE_ATLAS), R32F (float32: the Beckmann peak 1/m^2 reaches
400 at m = 0.05 and the tables are small, so there is no reason to give up precision for R16F),
LINEAR min/mag filtering, no mipmaps, CLAMP_TO_EDGE; uniform ``uSpecularTables``:

* rectangle ``"beckmann"``: Beckmann P(N.h, m), 512 x 256 texels, read by ``beckmann()``,
  ``beckmann_lookup()``, ``ks_skin_specular()``.
* rectangle ``"rho_dt"``: specular albedo a(cos, m) for rho_s = 1, 64 x 64 texels, read by
  ``rho_dt_lookup()``; diffuse keeps 1 - rho_s * a / pi.

One texture instead of two frees a sampler unit (GL guarantees 16 per stage, and tsd's final pass
needs one for the prefiltered environment): a lookup's footprint stays on its rectangle's texel
centres (specular_table_coord clamps to them), so it reads the same texels with the same weights
as a texture of the table alone (tests/test_specular.py compares them).

A Renderer uploads it once (``Renderer.specular_tables``) and every technique binds it at the
unit of the shading contract (dermis.techniques.shared.bind_specular_tables).

The s axis is the table's x (sqrt(1 - N.h), resp. sqrt(cos)), the t axis the log-spaced roughness;
numpy row 0 is uploaded first, which GL places at t = 0 (the bottom row), so numpy row j is texture
row j with no flip. The texel-centre mapping is in dermis/specular.py and specular_table_coord().
"""

from __future__ import annotations

import numpy as np

from dermis.specular import TABLE_ATLAS, TABLE_ATLAS_SIZE, beckmann_table, rho_dt_table



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


def specular_table_atlas() -> np.ndarray:
    """The float32 (rows, cols) atlas of dermis.specular.TABLE_ATLAS: each default table in its
    rectangle, zeros elsewhere."""
    cols, rows = TABLE_ATLAS_SIZE
    atlas = np.zeros((rows, cols), np.float32)
    for name, table in (("beckmann", beckmann_table()[0]), ("rho_dt", rho_dt_table())):
        x0, y0, w, h = TABLE_ATLAS[name]
        atlas[y0:y0 + h, x0:x0 + w] = table
    return atlas


def upload_specular_tables(ctx) -> dict:
    """Create the specular table atlas on ``ctx``: {"atlas": Texture}.

    The tables are built once per process (cached in dermis.specular); the caller owns the texture
    and releases it with the context. Use: ``tables["atlas"].use(unit)`` and set the sampler
    uniform to ``unit``.
    """
    return {"atlas": _float_table_texture(ctx, specular_table_atlas())}
