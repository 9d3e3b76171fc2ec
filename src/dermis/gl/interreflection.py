"""The interreflection bake (dermis.geometry.interreflection) as a texture for tsd's bounce gather:
rg32f, the texture-space (u, v) of each ray's first hit, (-1, -1) where the ray brings nothing.
Vertex v's K rays are the texels (x * K + k, y) with (x, y) = (v mod P, v div P), P = vertices per
row, so that a row is at most ROW_TEXELS wide (GL 4.5 guarantees 16384). Built once per product
key "interreflection_bake" (dermis.invalidation: the mesh) and texture-space layout."""

from __future__ import annotations

import moderngl
import numpy as np

from dermis.invalidation import fingerprint

ROW_TEXELS = 4096


def hit_layout(n_vertices: int, rays: int) -> tuple[int, int]:
    """(vertices per row, rows) of the hits texture and of the per-vertex bounce target."""
    per_row = max(1, ROW_TEXELS // max(int(rays), 1))
    return per_row, max(1, -(-int(n_vertices) // per_row))


class InterreflectionHits:
    """One technique's copy of the bake; ``get`` rebuilds it when the mesh or its layout changes."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.tex = None
        self.key = None
        self.per_row = 1
        self.rays = 0
        self.vertex_count = 0

    def get(self, frame):
        """The hits texture for ``frame``; appends "interreflection_bake" to frame.passes_run when built."""
        from dermis.geometry.interreflection import mesh_hits

        m = frame.scene.mesh
        uv_ts = m.uvs if m.texture_space_uvs is None else m.texture_space_uvs
        key = (frame.keys["interreflection_bake"], fingerprint(uv_ts))
        if key != self.key or self.tex is None:
            with frame.timer("interreflection_bake"):
                hits = mesh_hits(m)
                uv = hits.at_vertices(uv_ts, m.indices)  # (n, K, 2), NaN: nothing
                uv = np.where(np.isfinite(uv), uv, -1.0).astype(np.float32)
                n, k = hits.triangle.shape
                per_row, rows = hit_layout(n, k)
                data = np.full((rows * per_row, k, 2), -1.0, np.float32)
                data[:n] = uv
                self.release()
                self.tex = self.ctx.texture((per_row * k, rows), 2, dtype="f4")
                self.tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
                self.tex.write(np.ascontiguousarray(data.reshape(rows, per_row * k, 2)).tobytes())
                self.per_row, self.rays, self.vertex_count = per_row, k, n
            self.key = key
            frame.passes_run.append("interreflection_bake")
        return self.tex

    def release(self):
        if self.tex is not None:
            self.tex.release()
        self.tex = None
        self.key = None
