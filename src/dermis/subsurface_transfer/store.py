"""The baked subsurface transfer on disk: one .npz per mesh in dermis's cache folder
($DERMIS_CACHE_DIR, else $XDG_CACHE_HOME/dermis, else ~/.cache/dermis; under subsurface_transfer/),
named by the mesh's content (positions, triangles, texture-space uvs), found automatically for a
scene whose mesh, scale and skin medium are the ones baked. Any other scene, or a machine where the
bake was not built, renders without it.

It is generated data, not shipped: build it (minutes, one core; niced) with
    make subsurface-transfer          (the example head: examples/lee-perry-smith.toml)
    python -m dermis.subsurface_transfer SCENE.toml
The bake is seeded (seed 0): the same code and mesh give the same file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dermis.errors import DermisError
from dermis.geometry.texture_space import texture_space_uvs
from dermis.subsurface_transfer.bake import TransferBake

CACHE_SUBFOLDER = "subsurface_transfer"
FORMAT = 3  # 2 (round 11): per-point excess and its covariance; taps denoised (bake.denoise). 3 (round 22): tap_view
# (the first-order view term); the file name carries the format, so a format-2 file is never overwritten or misread
MEDIUM_TOLERANCE = 0.02  # relative: the scene's mean free path and mean albedo against the bake's


def mesh_key(mesh, format_: int = FORMAT) -> str:
    """The bake's name: SHA-256 of the mesh's positions, triangles and texture-space uvs (and, from format
    3, the format: a new format's bake gets its own file beside the older one)."""
    from dermis.geometry.atlas import content_hash

    uv = texture_space_uvs(mesh)
    extra = ("subsurface_transfer",) if format_ <= 2 else ("subsurface_transfer", f"format {format_}")
    return content_hash(mesh.positions, mesh.indices, *extra, np.asarray(uv, np.float32).tobytes())


def default_folder() -> Path | None:
    """Where bakes are written and looked up by default: dermis's cache folder (None: the disk cache
    is off, DERMIS_CACHE_DIR=off; then nothing is found and a bake needs an explicit folder)."""
    from dermis.profiles.scene_skin import _cache_folder

    base = _cache_folder()
    return None if base is None else base / CACHE_SUBFOLDER


def path_for(mesh, folder: Path | None = None) -> Path | None:
    folder = folder or default_folder()
    return None if folder is None else folder / (mesh_key(mesh)[:24] + ".npz")


def save(bake: TransferBake, path: Path, mesh_key_: str, mm_per_unit: float) -> None:
    """Write ``bake`` (taps' uv float32, weights and view terms float16: the weights are Monte Carlo
    estimates with several % noise, float16's 0.05 % is below it)."""
    meta = dict(bake.meta, format=FORMAT, mesh_key=mesh_key_, mm_per_unit=float(mm_per_unit))
    path.parent.mkdir(parents=True, exist_ok=True)
    from dermis.fileio import atomic_write

    def write(tmp):
        with open(tmp, "wb") as f:
            np.savez_compressed(f, point_uv=bake.point_uv.astype(np.float32), tap_uv=bake.tap_uv.astype(np.float32),
                                tap_weight=bake.tap_weight.astype(np.float16), kept=bake.kept.astype(np.float32),
                                subtracted=bake.subtracted.astype(np.float32), excess=_or_empty(bake.excess, 2),
                                excess_cov=_or_empty(bake.excess_cov, 3), meta=np.array(json.dumps(meta)),
                                tap_view=(np.zeros((0, 1, 3, 4), np.float16) if bake.tap_view is None
                                          else bake.tap_view.astype(np.float16)))

    # a temporary name of its own (atomic_write: not path + ".tmp"): two processes baking the same mesh at
    # once (the test suite's workers, pytest -n 2) each write whole files, and the last rename wins
    atomic_write(path, write)


def _or_empty(a, width: int) -> np.ndarray:
    return np.zeros((0, 3, width), np.float32) if a is None else np.asarray(a, np.float32)


class StaleBake(DermisError):
    """A bake written by another version of the format (:data:`FORMAT`) or made by another recipe
    (dermis.subsurface_transfer.bake.recipe_key: the estimator and denoising constants): rebuild it."""


REBUILD = "(rebuild it: make subsurface-transfer, or python -m dermis.subsurface_transfer SCENE.toml)"


def check_recipe(bake: TransferBake, path: Path) -> None:
    """Raise :class:`StaleBake` unless ``bake`` was made by this code's recipe (its meta's "recipe",
    absent in a bake older than round 12)."""
    from dermis.subsurface_transfer.bake import recipe_key

    got, want = bake.meta.get("recipe"), recipe_key()
    if got != want:
        raise StaleBake(f"{path}: subsurface transfer bake recipe {got}, expected {want} {REBUILD}")


def load(path: Path) -> TransferBake:
    try:
        with np.load(path) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != FORMAT:
                raise StaleBake(f"{path}: subsurface transfer bake format {meta.get('format')}, expected {FORMAT} {REBUILD}")
            bake = TransferBake(z["point_uv"], z["tap_uv"], z["tap_weight"].astype(np.float32), z["kept"],
                                z["subtracted"], meta, *(None if len(z[k]) == 0 else z[k] for k in ("excess", "excess_cov")),
                                tap_view=None if len(z["tap_view"]) == 0 else z["tap_view"].astype(np.float32))
    except (OSError, ValueError, KeyError) as e:
        raise DermisError(f"{path}: not a subsurface transfer bake ({e})") from None
    return bake


def scene_medium(scene) -> tuple[np.ndarray, np.ndarray]:
    """(mean free path per channel, mm; the skin's mean albedo): what the bake's medium is made from
    (dermis.subsurface_transfer.bake.skin_media), cheap to compare."""
    from dermis.profiles.thin_slab import slab_law
    from dermis.scene.model import mean_skin_albedo

    albedo = np.asarray(mean_skin_albedo(scene.material), np.float64)
    law = slab_law(scene.profile.normalized(), albedo)
    return 1.0 / np.asarray(law.reduced_sigma_t_per_mm, np.float64), albedo


def matches(bake: TransferBake, scene) -> bool:
    """Whether ``bake`` holds for ``scene``: its mesh, scale and medium (mean free path and mean albedo
    within MEDIUM_TOLERANCE)."""
    m = bake.meta
    if m.get("mesh_key") != mesh_key(scene.mesh) or abs(m.get("mm_per_unit", 0.0) - float(scene.mm_per_unit)) > 1e-6 * float(
            scene.mm_per_unit):
        return False
    mfp, albedo = scene_medium(scene)
    rel = lambda a, b: np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.maximum(np.abs(np.asarray(b)), 1e-12))
    return bool(rel(m["mean_free_path_mm"], mfp) <= MEDIUM_TOLERANCE and rel(m["albedo"], albedo) <= MEDIUM_TOLERANCE)


def find(scene, folder: Path | None = None) -> TransferBake | None:
    """The bake for ``scene`` (its mesh's file in ``folder``, default :func:`default_folder`) when it
    matches the scene (:func:`matches`) and was made by this code's format and recipe
    (:func:`check_recipe`), else None: the scene renders without it."""
    p = path_for(scene.mesh, folder)
    if p is None:
        return None
    if not p.is_file():
        # a bake of this mesh in an older format (its own file name, from format 3 on): say so, or the
        # scene would lose its transfer without a word after an update
        older = p.with_name(mesh_key(scene.mesh, 2)[:24] + ".npz")
        if older.is_file():
            import warnings

            warnings.warn(f"dermis: ignoring {older}: a subsurface transfer bake of an older format (2), expected "
                          f"{FORMAT} {REBUILD}", stacklevel=2)
        return None
    try:
        bake = load(p)
        check_recipe(bake, p)  # a bake of another recipe: the same file name, another result
    except StaleBake as e:  # an older dermis's bake: never misread, the scene renders without it
        import warnings

        warnings.warn(f"dermis: ignoring {e}", stacklevel=2)
        return None
    return bake if matches(bake, scene) else None


def bake_scene(scene, folder: Path | None = None, progress=print, **options) -> Path:
    """Bake ``scene``'s mesh with its medium and write it where :func:`find` looks."""
    from dermis.scene.model import mean_skin_albedo
    from dermis.subsurface_transfer.bake import (DEFAULT_GRID, NEAR_MM, THIN_MM, bake_points, bake_transfer,
                                                 denoise, recipe_key)

    p = path_for(scene.mesh, folder)
    if p is None:  # before minutes of walks, not after
        raise DermisError("the disk cache is off (DERMIS_CACHE_DIR=off): give the bake a folder (--out DIR)")
    albedo = mean_skin_albedo(scene.material)
    points = bake_points(scene.mesh, scene.mm_per_unit, options.get("grid", DEFAULT_GRID), options.get("thin_mm", THIN_MM),
                         options.get("near_mm", NEAR_MM))
    bake = bake_transfer(scene.mesh, scene.mm_per_unit, scene.profile, albedo, points=points, progress=progress, **options)
    bake = denoise(bake, points)
    bake.meta["recipe"] = recipe_key()  # bake_transfer and denoise at this code's defaults
    save(bake, p, mesh_key(scene.mesh), scene.mm_per_unit)
    return p
