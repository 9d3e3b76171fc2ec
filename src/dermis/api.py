"""The Python API: load a scene, render it, get numpy arrays back."""

from __future__ import annotations

import os
from pathlib import Path

from dermis.errors import DermisError
from dermis.scene.model import Scene


def load_scene(path, *, technique: str | None = None, uv_convention: str | None = None) -> Scene:
    """Load a TOML scene, or a bare mesh (.glb/.gltf/.obj) framed with default lights."""
    from dermis.scene.builtin import frame_scene
    from dermis.scene.loaders import load_mesh_file
    from dermis.scene.model import SkinMaterial
    from dermis.scene.toml_scene import load_scene_toml

    from dermis.scene.loaders import UV_CONVENTIONS
    from dermis.validation import check_scene, check_technique_arg

    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise DermisError(f"load_scene: path must be a str or os.PathLike, got {type(path).__name__}")
    if str(path) == "":
        raise DermisError("load_scene: path is empty")
    check_technique_arg(technique)
    if uv_convention is not None and uv_convention not in UV_CONVENTIONS:
        raise DermisError(f"uv_convention: must be one of {', '.join(UV_CONVENTIONS)}, got {uv_convention!r}")
    p = Path(path)
    if p.suffix.lower() == ".toml":
        scene = load_scene_toml(p)
    elif p.suffix.lower() in (".glb", ".gltf", ".obj"):
        mesh, mat = load_mesh_file(p, uv_convention)
        material = SkinMaterial(albedo=mat.get("albedo"), normal_map=mat.get("normal_map"))
        if mat.get("albedo_color") is not None and material.albedo is None:
            material.albedo_color = mat["albedo_color"]
        scene = Scene(mesh=mesh, material=material, source=str(p), name=p.stem, surfaces=list(mat.get("surfaces", [])))
        frame_scene(scene)
    elif not os.path.lexists(p):
        raise DermisError(f"{p}: file not found")
    else:
        raise DermisError(f"{p}: not a scene (.toml) or mesh (.glb, .gltf, .obj) file")
    if technique:
        scene.technique = technique
    check_scene(scene)
    return scene


def default_scene() -> Scene:
    """The built-in scene (procedural head, three-point light); needs no files."""
    from dermis.scene.builtin import default_scene as _d

    return _d()


def render(scene: Scene, technique: str | None = None, size=(512, 512), **renderer_options):
    """Render once and return linear float32 (H, W, 3) radiance. For many frames use Renderer.

    ``renderer_options``: those of Renderer (samples, shadow_size, irradiance_size, device, ctx)."""
    from dermis.renderer import Renderer
    from dermis.validation import check_scene, check_technique_arg

    unknown = sorted(set(renderer_options) - {"samples", "shadow_size", "irradiance_size", "device", "ctx", "timing"})
    if unknown:
        raise DermisError(f"render: unknown option(s) {', '.join(unknown)} (samples, shadow_size, irradiance_size, device)")
    check_technique_arg(technique)
    check_scene(scene)  # before a GL context is made

    with Renderer(scene, size, **renderer_options) as r:
        return r.render(technique)
