"""The per-vertex ray-cast bakes' shared parts: the distinct vertices they cast from, and their cache (dermis.geometry.visibility, dermis.geometry.interreflection):
in memory per content key (a few meshes) and on disk as .npz under the dermis cache folder, written to
a temporary name and renamed. A damaged or mismatched file is re-baked and overwritten; a read-only
cache folder only costs the re-bake."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.profiles.scene_skin import _cache_folder


def distinct_vertices(positions, normals):
    """What a per-vertex bake of a mesh (float32 ``positions``, ``normals`` (n, 3)) starts from:
    (unit normals in float64, a zero normal made +z; the index of the first copy of each distinct
    (position, normal); the inverse map back to every vertex; the bounding diagonal). One bake per
    distinct vertex: the copies of a vertex split along UV seams get the same rays, so the Monte
    Carlo noise does not draw the seams."""
    p = np.asarray(positions)
    nrm = np.asarray(normals)
    n64 = nrm.astype(np.float64)
    ln = np.linalg.norm(n64, axis=1, keepdims=True)
    n64 = np.where(ln > 0, n64 / np.maximum(ln, 1e-300), [[0.0, 0.0, 1.0]])
    diag = float(np.linalg.norm(p.max(0) - p.min(0))) if len(p) else 1.0
    _, first, inverse = np.unique(np.concatenate([p, nrm], axis=1), axis=0, return_index=True, return_inverse=True)
    return n64, first, inverse.reshape(-1), diag


_SOURCE_KEYS: dict = {}


def source_key(*modules) -> str | None:
    """A hash of ``modules``' source (remembered per process): a cached product keyed by it is rebuilt
    when the code that computes it changes. None where a module's source cannot be read (a frozen
    build): then the product is made, not stored."""
    names = tuple(m.__name__ for m in modules)
    if names not in _SOURCE_KEYS:
        import hashlib
        import inspect

        try:
            _SOURCE_KEYS[names] = hashlib.sha256("".join(inspect.getsource(m) for m in modules).encode()).hexdigest()
        except (OSError, TypeError):
            _SOURCE_KEYS[names] = None
    return _SOURCE_KEYS[names]


def cache_path(folder: str, key: str) -> Path | None:
    """Where the bake of content key ``key`` lives on disk (None: disk cache off)."""
    base = _cache_folder()
    return None if base is None else base / folder / (key[:32] + ".npz")


def load(memory: dict, key: str, path: Path | None, shapes: dict, keep: int) -> dict | None:
    """The arrays of ``key`` from ``memory`` or the file at ``path`` (then remembered, at most
    ``keep`` entries), or None. ``shapes``: name -> the shape the array must have (a file with any
    other is a miss; None: any)."""
    if key in memory:
        return memory[key]
    if path is None or not path.is_file():
        return None
    try:
        with np.load(path) as z:
            arrays = {name: z[name] for name in shapes}
    except (OSError, ValueError, KeyError):
        return None
    if any(shape is not None and arrays[name].shape != tuple(shape) for name, shape in shapes.items()):
        return None
    remember(memory, key, arrays, keep)
    return arrays


def remember(memory: dict, key: str, arrays: dict, keep: int):
    """Keep ``arrays`` under ``key``, forgetting the oldest entries beyond ``keep``."""
    while memory and len(memory) >= keep:
        memory.pop(next(iter(memory)))
    memory[key] = arrays


def store(path: Path | None, arrays: dict):
    """Write ``arrays`` to ``path`` (dermis.fileio.atomic_write: a temporary name of its own, then renamed, so
    two processes baking the same mesh at once each write whole files); errors only cost the re-bake."""
    if path is None:
        return
    from dermis.fileio import atomic_write

    def write(tmp):
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, write)
    except (OSError, DermisError):
        pass
