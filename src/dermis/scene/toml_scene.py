"""The TOML scene format (documented in docs/scene-format.md).

Every table and key is checked: a typo is named with its file, never ignored. Paths resolve
relative to the TOML file. Lengths of scattering are in mm; ``[scene] mm_per_unit`` converts
the mesh's units.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from dermis.camera import FOV_MAX_DEG, FOV_MIN_DEG, normalize
from dermis.errors import DermisError
from dermis.fileio import read_text, regular_file
from dermis.images import MAX_IMAGE_PIXELS, as_rgb, read_image
from dermis.invalidation import immutable
from dermis.output import TONEMAPS
from dermis.scene.model import SKIN_COLORS, Camera, Environment, Light, Output, Scene, SkinMaterial, Texture
from dermis.techniques.shared import MAX_LIGHTS
from dermis.validation import check_exposure, check_scene

# key -> expected python type(s); lists of numbers are checked for length
_SCHEMA = {
    "scene": {"name": str, "mm_per_unit": float, "technique": str, "interreflection": bool,
              "translucency_light_path": bool, "directional_albedo": bool},
    "mesh": {"file": str, "builtin": str, "uv_convention": str, "texture_space_uv": str},
    "material": {"albedo": str, "albedo_color": "rgb", "normal_map": str, "normal_strength": float,
                 "specular_map": str, "roughness": float, "roughness_map": str, "rho_s": float, "specular_map_bias": float,
                 "specular_map_scale": float, "mix": float, "pore_scale_mm": float, "pore_strength": float,
                 "double_sided": bool},
    "light": {"type": str, "color": "rgb", "intensity": float, "direction": "vec3", "position": "vec3",
              "target": "vec3", "spot_angle_deg": float, "spot_blend": float, "cast_shadows": bool,
              "shadow_softness": float, "shadow_bias": float},
    "camera": {"position": "vec3", "target": "vec3", "up": "vec3", "fov_deg": float, "near": float, "far": float,
               "fit": bool},
    "environment": {"color": "rgb", "image": str, "intensity": float, "occlusion": bool, "rotation": float},
    "output": {"exposure": float, "tonemap": str, "background": "rgb", "bloom": float, "bloom_radius": float},
}
_TOP = {"scene", "mesh", "material", "lights", "camera", "environment", "output", "skin"}


def _check(table: dict, section: str, source) -> dict:
    schema = _SCHEMA[section]
    out = {}
    for key, value in table.items():
        if key not in schema:
            near = [k for k in schema if k[:3] == key[:3]]
            hint = f" (did you mean '{near[0]}'?)" if near else ""
            raise DermisError(f"{source}: unknown key '{key}' in [{section}]{hint}")
        kind = schema[key]
        where = f"{source}: [{section}] {key}"
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise DermisError(f"{where} must be a finite number, got {value!r}")
            value = float(value)
        elif kind in ("rgb", "vec3"):
            if not isinstance(value, list) or len(value) != 3 or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value):
                raise DermisError(f"{where} must be a list of 3 finite numbers, got {value!r}")
            if kind == "rgb" and min(value) < 0:
                raise DermisError(f"{where} must not be negative")
            value = tuple(float(x) for x in value)
        elif not isinstance(value, kind):
            raise DermisError(f"{where} must be a {kind.__name__}, got {value!r}")
        elif kind is str and any(c < " " for c in value):  # a NUL or newline names no file and breaks a message
            raise DermisError(f"{where} must not contain control characters, got {value[:200]!r}")
        out[key] = value
    return out


def _texture(folder: Path, rel: str, srgb: bool, source, max_pixels: int, rgb: bool = True) -> Texture:
    """A texture file as float32; ``rgb``: grey images are replicated to three channels."""
    p = (folder / rel)
    try:
        regular_file(p, "texture")
    except DermisError as exc:
        raise DermisError(f"{source}: texture '{rel[:200]}': {str(exc).split(': ', 1)[-1]} (looked for {str(p)[:300]})") from None
    arr = read_image(p, srgb=srgb, max_pixels=max_pixels)
    # immutable: its content key is computed once, not every frame (dermis.invalidation)
    return Texture(immutable(as_rgb(arr) if rgb else arr), str(p))


def _positive(value, name, source, lo=0.0, hi=None, inclusive=False):
    bad = value < lo or (value == lo and not inclusive) or (hi is not None and value > hi)
    if bad:
        rng = f"in ({lo}, {hi}]" if hi is not None else f"> {lo}"
        raise DermisError(f"{source}: {name} must be {rng}, got {value}")


def parse_light(d: dict, source, index: int) -> Light:
    d = _check(d, "light", source)
    kind = d.pop("type", "directional")
    if kind not in ("directional", "point", "spot"):
        raise DermisError(f"{source}: [[lights]] #{index + 1} type must be directional, point or spot, got '{kind}'")
    target = d.pop("target", None)
    light = Light(kind=kind, **{("shadow_softness" if k == "shadow_softness" else k): v for k, v in d.items()})
    if target is not None:
        direction = np.asarray(target) - np.asarray(light.position)
        light.direction = tuple(normalize(direction))
    if np.linalg.norm(light.direction) < 1e-9:
        raise DermisError(f"{source}: [[lights]] #{index + 1} direction must not be zero")
    light.direction = tuple(normalize(light.direction))
    _positive(light.intensity, f"[[lights]] #{index + 1} intensity", source, 0.0, inclusive=True)
    return light


def read_toml(path: Path, kind: str = "scene") -> dict:
    """A TOML file (a scene, a sweep) as a dict, with one-line errors naming the file."""
    text = read_text(path, f"{kind} file")  # regular files only; OS errors as one line
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DermisError(f"{path}: invalid TOML ({exc})") from None


def load_scene_toml(path, max_pixels: int = MAX_IMAGE_PIXELS) -> Scene:
    from dermis.scene.builtin import builtin_mesh
    from dermis.scene.loaders import load_mesh_file

    path = Path(path)
    doc = read_toml(path, "scene")
    folder = path.resolve().parent
    for key in doc:
        if key not in _TOP:
            raise DermisError(f"{path}: unknown table or key '{key}' (expected one of {', '.join(sorted(_TOP))})")
        if key != "lights" and not isinstance(doc[key], dict):
            raise DermisError(f"{path}: '{key}' must be a table [{key}]")
    sc = _check(doc.get("scene", {}), "scene", path)
    mesh_t = _check(doc.get("mesh", {}), "mesh", path)
    mat_t = _check(doc.get("material", {}), "material", path)

    # mesh
    if ("file" in mesh_t) == ("builtin" in mesh_t):
        raise DermisError(f"{path}: [mesh] needs exactly one of 'file' or 'builtin'")
    material_from_file = {}
    builtin_material = None
    if "file" in mesh_t:
        mesh, material_from_file = load_mesh_file(folder / mesh_t["file"], mesh_t.get("uv_convention"), max_pixels,
                                                  skin_materials(doc.get("skin", {}), path))
        default_mm = 1.0
    else:
        if skin_materials(doc.get("skin", {}), path) is not None:
            raise DermisError(f"{path}: [skin] materials chooses a glTF mesh's materials; [mesh] builtin has none")
        mesh, builtin_material, default_mm = builtin_mesh(mesh_t["builtin"], source=path)
    if "texture_space_uv" in mesh_t:  # the UV set tsd works in (dermis.geometry.texture_space)
        from dermis.geometry.texture_space import MODES

        if mesh_t["texture_space_uv"] not in MODES:
            raise DermisError(f"{path}: [mesh] texture_space_uv must be one of {', '.join(MODES)}, "
                              f"got '{mesh_t['texture_space_uv']}'")
        mesh.texture_space_uv = mesh_t["texture_space_uv"]
    mm_per_unit = sc.get("mm_per_unit", default_mm)
    _positive(mm_per_unit, "[scene] mm_per_unit", path)

    # material
    mat = builtin_material or SkinMaterial()
    for k in ("albedo", "normal_map", "specular_map"):
        if material_from_file.get(k) is not None:
            setattr(mat, k, material_from_file[k])
    if material_from_file.get("albedo_color") is not None and mat.albedo is None:
        mat.albedo_color = material_from_file["albedo_color"]
    for k, v in mat_t.items():
        if k == "albedo":
            mat.albedo = _texture(folder, v, True, path, max_pixels)
        elif k == "normal_map":
            mat.normal_map = _texture(folder, v, False, path, max_pixels)
        elif k in ("specular_map", "roughness_map"):
            t = _texture(folder, v, False, path, max_pixels, rgb=False)
            setattr(mat, k, Texture(t.data[:, :, :1], t.source))
        else:
            setattr(mat, k, v)
    _positive(mat.roughness, "[material] roughness", path, 0.0, 1.0)
    _positive(mat.rho_s, "[material] rho_s", path, 0.0, 1.0, inclusive=True)
    if not 0.0 <= mat.mix <= 1.0:
        raise DermisError(f"{path}: [material] mix must be in [0, 1], got {mat.mix}")

    # lights
    lights_t = doc.get("lights", [])
    if not isinstance(lights_t, list) or not all(isinstance(x, dict) for x in lights_t):
        raise DermisError(f"{path}: 'lights' must be an array of tables [[lights]]")
    lights = [parse_light(d, path, i) for i, d in enumerate(lights_t)]
    if len(lights) > MAX_LIGHTS:
        raise DermisError(f"{path}: at most {MAX_LIGHTS} lights are supported, got {len(lights)}")

    cam = Camera(**_check(doc.get("camera", {}), "camera", path))
    if not FOV_MIN_DEG <= cam.fov_deg < FOV_MAX_DEG:
        raise DermisError(f"{path}: [camera] fov_deg must be in [{FOV_MIN_DEG:g}, {FOV_MAX_DEG:g}) degrees, got {cam.fov_deg}")
    env_t = _check(doc.get("environment", {}), "environment", path)
    env = Environment(color=env_t.get("color", Environment.color), intensity=env_t.get("intensity", 1.0),
                      occlusion=env_t.get("occlusion", True), rotation_deg=env_t.get("rotation", 0.0))
    if "image" in env_t:
        env.image = _texture(folder, env_t["image"], True, path, max_pixels)
    out = Output(**_check(doc.get("output", {}), "output", path))
    if not 0.0 <= out.bloom <= 1.0 or not 0.0 < out.bloom_radius <= 0.5:
        raise DermisError(f"{path}: [output] bloom must be in [0, 1] and bloom_radius in (0, 0.5]")
    check_exposure(out.exposure, f"{path}: [output] exposure")
    if out.tonemap not in TONEMAPS:
        raise DermisError(f"{path}: [output] tonemap must be one of {', '.join(TONEMAPS)}, got '{out.tonemap}'")

    profile, skin_color = resolve_profile_section(doc.get("skin", {}), folder, path)
    technique = sc.get("technique", "tsd")
    scene = Scene(mesh=mesh, material=mat, lights=lights, camera=cam, environment=env, output=out,
                  mm_per_unit=mm_per_unit, profile=profile, skin_color=skin_color, technique=technique, source=str(path),
                  name=sc.get("name", path.stem), surfaces=list(material_from_file.get("surfaces", [])),
                  interreflection=sc.get("interreflection", True),
                  translucency_light_path=sc.get("translucency_light_path", False),
                  directional_albedo=sc.get("directional_albedo", True))
    if not lights_t and not doc.get("camera"):
        from dermis.scene.builtin import frame_scene

        frame_scene(scene)
    elif not doc.get("camera"):
        from dermis.scene.builtin import frame_camera

        frame_camera(scene)
    check_scene(scene)
    return scene




def skin_materials(section, source) -> list | None:
    """[skin] materials: the glTF materials rendered as skin, by name or index (None: not given)."""
    if not isinstance(section, dict) or "materials" not in section:
        return None
    v = section["materials"]
    if not isinstance(v, list) or not v or not all(
            isinstance(x, str) or (isinstance(x, int) and not isinstance(x, bool) and x >= 0) for x in v):
        raise DermisError(f"{source}: [skin] materials must be a non-empty array of material names or indices, got {v!r}")
    return v


def resolve_profile_section(section: dict, folder: Path, source):
    """[skin] -> (SumOfGaussians, skin_color). ``color`` says where the skin's total diffuse
    colour comes from: "albedo" (the map; default for "deon" and profile files) or "profile" (the
    physical profile's total reflectance; default for presets and physical parameters, so that
    melanin darkens the skin)."""
    if not isinstance(section, dict):
        raise DermisError(f"{source}: [skin] must be a table")
    from dermis import profiles

    section = dict(section)
    section.pop("materials", None)  # the mesh's skin materials (skin_materials), not the profile's
    color = section.pop("color", None)
    kind = section.get("profile", "deon")
    if color is None:
        color = "profile" if kind in (*profiles.SKIN_PRESETS, "physical", "medium") else "albedo"
    if color not in SKIN_COLORS:
        raise DermisError(f"{source}: [skin] color must be one of {', '.join(SKIN_COLORS)}, got {color!r}")
    return profiles.resolve_skin_profile(section, folder, str(source)), color
