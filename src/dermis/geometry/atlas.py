"""Texture atlases from xatlas (Young, "xatlas", github.com/jpcy/xatlas; the library Godot uses
for its light-map UVs): the mesh is cut into charts, each is parameterised (least-squares
conformal maps) and the charts are packed into one square image with ``padding_px`` empty
texels around every chart, so filters that reach that far do not mix charts.

The result splits vertices where a chart boundary runs: ``vmapping`` gives, for every atlas
vertex, the input vertex it copies. Results are cached on disk (under $DERMIS_CACHE_DIR, else
$XDG_CACHE_HOME/dermis, else ~/.cache/dermis; DERMIS_CACHE_DIR=off disables it), keyed by the
SHA-256 of the positions, the triangles, the options and the xatlas version, so an edited mesh
never reuses a stale atlas.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.geometry import bake_cache
from dermis.profiles.scene_skin import _cache_folder

CACHE_VERSION = 1  # bump when the options passed to xatlas change meaning (join_boxes: in the key only when given)


@dataclass(frozen=True)
class Atlas:
    vmapping: np.ndarray  # (V',) int64: the input vertex each atlas vertex copies
    indices: np.ndarray  # (M, 3) uint32: the input triangles, in order, on atlas vertices
    uvs: np.ndarray  # (V', 2) float32 in [0, 1], v up (dermis convention)
    resolution: int  # texels along each side the packing was done for
    padding_px: int  # empty texels around every chart at that resolution
    utilization: float  # fraction of the image charts cover
    seconds: float  # time to generate (0 when read from the cache)
    cached: bool  # read from the disk cache


def content_hash(positions, indices, *extra) -> str:
    """SHA-256 of a mesh's positions (float32) and triangles (uint32) and of ``extra``."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(positions, np.float32).tobytes())
    h.update(np.ascontiguousarray(indices, np.uint32).tobytes())
    h.update(repr(extra).encode())
    return h.hexdigest()


def _cache_path(key: str) -> Path | None:
    folder = _cache_folder()
    return None if folder is None else folder / "atlas" / (key[:32] + ".npz")


def _xatlas(xatlas, p, t, resolution, padding_px, uvs=None):
    """(xatlas.Atlas, vmapping, indices, uvs with v up in the square image) of one generation; ``uvs``: the
    charts given as UV islands (only packed)."""
    atlas = xatlas.Atlas()
    if uvs is None:
        atlas.add_mesh(p, t)
    else:
        atlas.add_mesh(p, t, uvs=np.ascontiguousarray(uvs, np.float32))
    chart = xatlas.ChartOptions()
    chart.use_input_mesh_uvs = uvs is not None
    pack = xatlas.PackOptions()
    pack.resolution = resolution
    pack.padding = padding_px
    pack.bilinear = True  # a texel's bilinear footprint stays inside its chart
    pack.texels_per_unit = 0.0  # scale to fill one image of `resolution`
    atlas.generate(chart, pack)
    if atlas.atlas_count != 1:
        raise DermisError(f"xatlas packed the mesh into {atlas.atlas_count} images; dermis needs one")
    vmapping, idx, uv = atlas.get_mesh(0)
    # xatlas measures from the image's top-left (texel rows downwards); dermis has v up. The
    # packing is done for the atlas's own width x height, scaled into the square image.
    w, h = atlas.width, atlas.height
    uv = np.asarray(uv, np.float64) * np.array([w, h]) / float(max(w, h))
    uv[:, 1] = 1.0 - uv[:, 1]
    return atlas, np.asarray(vmapping, np.int64), np.asarray(idx, np.int64).reshape(-1, 3), uv


def generate_atlas(positions, indices, *, resolution: int = 1024, padding_px: int = 4, cache: bool = True,
                   join_boxes=()) -> Atlas:
    """One xatlas atlas of the triangle mesh (``positions`` (N, 3), ``indices`` (M, 3)) packed
    into a ``resolution`` square with ``padding_px`` texels of gutter around every chart.
    ``join_boxes``: ((lo xyz), (hi xyz)) boxes in mesh units; the charts reaching into each become one
    chart, flattened anew (dermis.geometry.parameterize.join_charts): no seam inside a box."""
    try:
        import xatlas
    except ImportError as exc:  # pragma: no cover - xatlas is a dependency
        raise DermisError(f"generating a UV atlas needs the 'xatlas' package ({exc})") from None
    resolution, padding_px = int(resolution), int(padding_px)
    if resolution < 16 or padding_px < 0:
        raise DermisError(f"atlas resolution must be >= 16 and padding >= 0, got {resolution}, {padding_px}")
    p = np.ascontiguousarray(positions, np.float32).reshape(-1, 3)
    t = np.ascontiguousarray(indices, np.uint32).reshape(-1, 3)
    join_boxes = tuple(tuple(tuple(float(x) for x in c) for c in box) for box in join_boxes)
    if join_boxes:
        from dermis.geometry.parameterize import JOIN_MIN_TRIANGLES, JOIN_VERSION

        # libigl flattens the joined charts (dermis.geometry.parameterize): its release keys them as xatlas's does
        extra = (join_boxes, JOIN_MIN_TRIANGLES, JOIN_VERSION, metadata.version("libigl"))
    else:
        extra = ()  # keys of atlases without boxes unchanged
    key = content_hash(p, t, CACHE_VERSION, resolution, padding_px, metadata.version("xatlas"), *extra)
    path = _cache_path(key) if cache else None
    if path is not None and path.is_file():
        try:
            with np.load(path) as z:
                return Atlas(z["vmapping"], z["indices"], z["uvs"], resolution, padding_px, float(z["utilization"]),
                             0.0, True)
        except (OSError, ValueError, KeyError):
            pass  # a damaged cache file is regenerated and overwritten
    t0 = time.perf_counter()
    atlas, vmapping, idx, uv = _xatlas(xatlas, p, t, resolution, padding_px)
    if join_boxes:
        from dermis.geometry.parameterize import join_charts

        vm1, idx1, uv1 = join_charts(p, t, vmapping, idx, uv, join_boxes)
        atlas, vm2, idx, uv = _xatlas(xatlas, p[vm1], idx1.astype(np.uint32), resolution, padding_px, uv1)
        vmapping = vm1[vm2]
    result = Atlas(vmapping, np.asarray(idx, np.uint32).reshape(-1, 3), uv.astype(np.float32),
                   resolution, padding_px, float(np.mean(atlas.utilization)), time.perf_counter() - t0, False)
    # a read-only cache folder only costs the regeneration
    bake_cache.store(path, dict(vmapping=result.vmapping, indices=result.indices, uvs=result.uvs,
                                utilization=result.utilization))
    return result


def atlas_on_welded_surface(positions, indices, resolution: int = 1024, padding_px: int = 4, cache: bool = True,
                            join_boxes=()):
    """An xatlas layout of the surface with vertices welded by position, so that charts may
    cross the asset's own UV seams (a mirrored head's midline, a cylinder's wrap) instead of every
    such seam becoming a texture-space seam too; then every triangle corner gets a vertex for
    each distinct (atlas vertex, asset vertex) pair, so both UV sets stay per vertex.
    Returns (input vertex of each new vertex, triangles (M, 3) uint32 in the input's order, UVs)."""
    p = np.asarray(positions)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    _, first, weld = np.unique(p, axis=0, return_index=True, return_inverse=True)
    weld = weld.reshape(-1)
    atlas = generate_atlas(p[first], weld[t], resolution=resolution, padding_px=padding_px, cache=cache,
                           join_boxes=join_boxes)
    # xatlas keeps the triangles in order: corner (f, k) is atlas vertex atlas.indices[f, k] and
    # asset vertex t[f, k]
    n = len(p)
    pairs = atlas.indices.astype(np.int64).reshape(-1) * n + t.reshape(-1)  # one int64 key per pair
    uniq, inv = np.unique(pairs, return_inverse=True)
    return uniq % n, inv.reshape(-1, 3).astype(np.uint32), atlas.uvs[uniq // n]
