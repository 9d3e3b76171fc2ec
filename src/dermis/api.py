"""The Python API: load a scene, render it, get numpy arrays back."""

from __future__ import annotations

from pathlib import Path

from dermis.errors import DermisError
from dermis.scene.model import Scene


def load_scene(path, *, technique: str | None = None, uv_convention: str | None = None) -> Scene:
    """Load a TOML scene, or a bare mesh (.glb/.gltf/.obj) framed with default lights."""
    from dermis.scene.builtin import frame_scene
    from dermis.scene.loaders import load_mesh_file
    from dermis.scene.model import SkinMaterial
    from dermis.scene.toml_scene import load_scene_toml

    p = Path(path)
    if p.suffix.lower() == ".toml":
        scene = load_scene_toml(p)
    elif p.suffix.lower() in (".glb", ".gltf", ".obj"):
        mesh, mat = load_mesh_file(p, uv_convention)
        material = SkinMaterial(albedo=mat.get("albedo"), normal_map=mat.get("normal_map"))
        if mat.get("albedo_color") is not None and material.albedo is None:
            material.albedo_color = mat["albedo_color"]
        scene = Scene(mesh=mesh, material=material, source=str(p), name=p.stem)
        frame_scene(scene)
    elif not p.exists():
        raise DermisError(f"{p}: file not found")
    else:
        raise DermisError(f"{p}: not a scene (.toml) or mesh (.glb, .gltf, .obj) file")
    if technique:
        scene.technique = technique
    return scene


def default_scene() -> Scene:
    """The built-in scene (procedural head, three-point light); needs no files."""
    from dermis.scene.builtin import default_scene as _d

    return _d()


def render(scene: Scene, technique: str | None = None, size=(512, 512), **renderer_options):
    """Render once and return linear float32 (H, W, 3) radiance. For many frames use Renderer."""
    from dermis.renderer import Renderer

    with Renderer(scene, size, **renderer_options) as r:
        return r.render(technique)
