"""A dermis scene as a Blender scene (bpy data): mesh, skin material, camera, lights, world.

``build_scene`` fills the current (emptied) Blender session; ``export_blend`` writes it to a
.blend an artist opens in Blender to see the same picture lit the same way. Units and
conventions: dermis.blender.convert. The original dermis values are kept as custom properties
(``dermis_*``) so dermis.blender.reimport reads them back exactly.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dermis.blender import convert, quiet_fds, require_bpy
from dermis.errors import DermisError


@dataclass
class ExportOptions:
    sss: bool = True  # skin as random-walk subsurface; False: the Cycles control (plain diffuse)
    specular: bool = True  # the skin's specular lobe; False: diffuse only (calibration)
    texture_dir: Path | None = None  # where in-memory textures (no source file) are written


def _own_file(tex) -> str | None:
    """The dermis Texture's own source file, if it has one on disk (not the built-in head's arrays,
    not an image embedded in a glTF)."""
    src = getattr(tex, "source", "") or ""
    return src if src and Path(src).is_file() else None


def _image_path(tex, name, opts) -> str:
    """The file behind a dermis Texture: its own source file when there is one (absolute path),
    else the array written beside the export (EXR, linear) so nothing is lost."""
    src = _own_file(tex)
    if src:
        return os.path.abspath(src)
    from dermis.images import write_exr

    folder = Path(opts.texture_dir) if opts.texture_dir else Path(tempfile.mkdtemp(prefix="dermis-blend-"))
    folder.mkdir(parents=True, exist_ok=True)
    data = np.asarray(tex.data, np.float32)
    if data.ndim == 2:
        data = data[:, :, None]
    if data.shape[2] == 1:
        data = np.repeat(data, 3, axis=2)
    path = folder / f"{name}.exr"
    write_exr(path, data[:, :, :3])
    return os.path.abspath(path)


def _load_image(bpy, path, colorspace):
    img = bpy.data.images.load(path, check_existing=True)
    img.colorspace_settings.name = colorspace
    return img


def _linear_space(bpy):
    names = {c.name for c in bpy.types.ColorManagedInputColorspaceSettings.bl_rna.properties["name"].enum_items}
    return "Linear Rec.709" if "Linear Rec.709" in names else "Linear"


def build_mesh(bpy, scene):
    """Mesh object: positions merged where they coincide (UV seams become loop UVs, as artists
    expect), dermis's normals as custom split normals, UVs as they are (both v-up)."""
    m = scene.mesh
    mpu = convert.metres_per_unit(scene)
    pos = np.asarray(m.positions, np.float64)
    key = np.round(pos * 1e6 / max(np.abs(pos).max(), 1e-30)).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    verts = convert.to_blender_points(pos[first], mpu).astype(np.float32)
    idx = np.asarray(m.indices, np.int64).reshape(-1, 3)
    corner = idx.reshape(-1)
    me = bpy.data.meshes.new(scene.name or "dermis")
    me.vertices.add(len(verts))
    me.vertices.foreach_set("co", verts.ravel())
    me.loops.add(len(corner))
    me.loops.foreach_set("vertex_index", inv[corner].astype(np.int32))
    me.polygons.add(len(idx))
    me.polygons.foreach_set("loop_start", (np.arange(len(idx)) * 3).astype(np.int32))
    me.polygons.foreach_set("loop_total", np.full(len(idx), 3, np.int32))
    uv = me.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", np.asarray(m.uvs, np.float32)[corner].ravel())
    me.update(calc_edges=True)
    me.polygons.foreach_set("use_smooth", np.ones(len(idx), bool))
    n = convert.to_blender_dirs(np.asarray(m.normals, np.float64)[corner])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    me.normals_split_custom_set(n.astype(np.float32))
    me.update()
    obj = bpy.data.objects.new(scene.name or "dermis", me)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def build_material(bpy, scene, opts: ExportOptions):
    """Principled BSDF: albedo map (sRGB) as base colour; tangent-space normal map through Blender's
    MikkTSpace tangents (dermis's tangents are MikkTSpace too); specular rho_s (bias + scale map)
    as Specular IOR Level with IOR 1.4 (F0 = 0.028); random-walk subsurface with the radius fitted
    to the scene's diffusion profile (dermis.blender.sss)."""
    from dermis.blender import sss

    mat_d = scene.material
    mat = bpy.data.materials.new("skin")
    mat.use_nodes = True
    nt = mat.node_tree
    nodes, links = nt.nodes, nt.links
    bsdf = nodes.get("Principled BSDF")
    linear = _linear_space(bpy)
    uvmap = nodes.new("ShaderNodeUVMap")
    uvmap.uv_map = "UVMap"

    def tex_node(tex, name, space):
        node = nodes.new("ShaderNodeTexImage")
        node.name = node.label = name
        path = _image_path(tex, name, opts)
        if space == "sRGB" and Path(path).suffix.lower() in (".exr", ".hdr"):
            # dermis reads HDR files as linear (dermis.images.read_image), and an in-memory map is
            # written as an EXR of its linear values (_image_path); Blender decodes float images by
            # their colorspace too, so "sRGB" would decode them a second time (0.5 -> 0.214).
            space = linear
        node.image = _load_image(bpy, path, space)
        node.interpolation = "Linear"
        links.new(uvmap.outputs["UV"], node.inputs["Vector"])
        return node

    scale = sss.albedo_scale(scene)
    if opts.sss:
        scale = scale * sss.cycles_subsurface(scene).base_gain
    if mat_d.albedo is not None:
        base = tex_node(mat_d.albedo, "albedo", "sRGB").outputs["Color"]
    else:
        rgb = nodes.new("ShaderNodeRGB")
        rgb.outputs[0].default_value = (*[float(c) for c in mat_d.albedo_color], 1.0)
        base = rgb.outputs[0]
    if not np.allclose(scale, 1.0):
        mul = nodes.new("ShaderNodeMix")
        mul.data_type, mul.blend_type = "RGBA", "MULTIPLY"
        mul.inputs["Factor"].default_value = 1.0
        links.new(base, mul.inputs[6])
        mul.inputs[7].default_value = (*[float(c) for c in scale], 1.0)
        base = mul.outputs[2]
    links.new(base, bsdf.inputs["Base Color"])

    if mat_d.normal_map is not None:
        nm = nodes.new("ShaderNodeNormalMap")
        nm.space, nm.uv_map = "TANGENT", "UVMap"
        nm.inputs["Strength"].default_value = float(mat_d.normal_strength)
        links.new(tex_node(mat_d.normal_map, "normal_map", "Non-Color").outputs["Color"], nm.inputs["Color"])
        links.new(nm.outputs["Normal"], bsdf.inputs["Normal"])

    bsdf.inputs["IOR"].default_value = 1.4
    if opts.specular:
        level = convert.specular_ior_level(mat_d.rho_s)
        if mat_d.specular_map is not None:
            spec = tex_node(mat_d.specular_map, "specular_map", "Non-Color")
            sep = nodes.new("ShaderNodeSeparateColor")
            links.new(spec.outputs["Color"], sep.inputs["Color"])
            ma = nodes.new("ShaderNodeMath")  # level * (bias + scale * map)
            ma.operation = "MULTIPLY_ADD"
            links.new(sep.outputs[0], ma.inputs[0])
            ma.inputs[1].default_value = float(level * mat_d.specular_map_scale)
            ma.inputs[2].default_value = float(level * mat_d.specular_map_bias)
            links.new(ma.outputs[0], bsdf.inputs["Specular IOR Level"])
        else:
            bsdf.inputs["Specular IOR Level"].default_value = float(level * mat_d.specular_map_bias)
        if mat_d.roughness_map is not None:
            rough = tex_node(mat_d.roughness_map, "roughness_map", "Non-Color")
            sep = nodes.new("ShaderNodeSeparateColor")
            links.new(rough.outputs["Color"], sep.inputs["Color"])
            pw = nodes.new("ShaderNodeMath")
            pw.operation = "POWER"
            pw.inputs[1].default_value = 0.5
            links.new(sep.outputs[0], pw.inputs[0])
            links.new(pw.outputs[0], bsdf.inputs["Roughness"])
        else:
            bsdf.inputs["Roughness"].default_value = float(convert.principled_roughness(mat_d.roughness))
    else:
        bsdf.inputs["Specular IOR Level"].default_value = 0.0
        bsdf.inputs["Roughness"].default_value = 1.0

    if opts.sss:
        p = sss.cycles_subsurface(scene)
        bsdf.subsurface_method = p.method
        bsdf.inputs["Subsurface Weight"].default_value = 1.0
        bsdf.inputs["Subsurface Radius"].default_value = tuple(float(r) for r in p.radius_mm)
        bsdf.inputs["Subsurface Scale"].default_value = 1e-3  # radius in mm, Blender units metres
        if "Subsurface IOR" in bsdf.inputs:
            bsdf.inputs["Subsurface IOR"].default_value = p.ior
        bsdf.inputs["Subsurface Anisotropy"].default_value = p.anisotropy
    else:
        bsdf.inputs["Subsurface Weight"].default_value = 0.0
    mat["dermis_rho_s"] = float(mat_d.rho_s)
    mat["dermis_roughness"] = float(mat_d.roughness)
    return mat


def build_camera(bpy, scene, aspect: float = 1.0):
    # the camera dermis renders with: with [camera] fit, fitted to the mesh for this aspect (dermis.framing)
    from dermis.framing import framed_camera

    cam_d = framed_camera(scene.camera, scene.mesh, aspect)
    mpu = convert.metres_per_unit(scene)
    cam = bpy.data.cameras.new("camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = math.radians(cam_d.fov_deg)
    lo, hi = scene.bounds()
    from dermis.camera import bounding_sphere

    c, r = bounding_sphere(lo, hi)
    d = float(np.linalg.norm(np.asarray(cam_d.position, np.float64) - c))
    cam.clip_start = float((cam_d.near or max(d - 1.5 * r, r * 1e-3, 1e-4)) * mpu)
    cam.clip_end = float((cam_d.far or d + 1.5 * r) * mpu * 10)
    obj = bpy.data.objects.new("camera", cam)
    fwd = np.asarray(cam_d.target, np.float64) - np.asarray(cam_d.position, np.float64)
    obj.matrix_world = convert.object_matrix(cam_d.position, fwd, cam_d.up, mpu).T.tolist()
    # exact round trip: what Blender's matrix cannot hold
    obj["dermis_position"] = [float(x) for x in cam_d.position]
    obj["dermis_target"] = [float(x) for x in cam_d.target]
    obj["dermis_up"] = [float(x) for x in cam_d.up]
    obj["dermis_fov_deg"] = float(cam_d.fov_deg)
    obj["dermis_fit"] = bool(getattr(scene.camera, "fit", False))  # the pose above is the fitted one
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.scene.camera = obj
    return obj


def build_lights(bpy, scene):
    mpu = convert.metres_per_unit(scene)
    objs = []
    for i, L in enumerate(scene.lights):
        name = f"{L.kind}_{i}"
        if L.kind == "directional":
            light = bpy.data.lights.new(name, "SUN")
            light.energy = float(L.intensity)  # W/m^2, irradiance at normal incidence
            light.angle = 0.0  # a delta light, as in dermis
        elif L.kind in ("point", "spot"):
            light = bpy.data.lights.new(name, "POINT" if L.kind == "point" else "SPOT")
            light.energy = convert.point_power_w(L.intensity)
            light.shadow_soft_size = 0.0
            if L.kind == "spot":
                light.spot_size = math.radians(2 * L.spot_angle_deg)
                light.spot_blend = convert.spot_blend_cycles(L.spot_angle_deg, L.spot_blend)
        else:
            raise DermisError(f"{scene.source}: light #{i + 1}: unknown type '{L.kind}'")
        light.color = tuple(float(c) for c in L.color)
        light.use_shadow = bool(L.cast_shadows)
        obj = bpy.data.objects.new(name, light)
        pos = L.position if L.kind != "directional" else (0.0, 0.0, 0.0)
        fwd = L.direction if L.kind != "point" else (0.0, -1.0, 0.0)
        obj.matrix_world = convert.object_matrix(pos, fwd, (0.0, 1.0, 0.0), mpu).T.tolist()
        for k in ("intensity", "spot_angle_deg", "spot_blend", "shadow_softness", "shadow_bias"):
            obj[f"dermis_{k}"] = float(getattr(L, k))
        obj["dermis_kind"] = L.kind
        obj["dermis_color"] = [float(c) for c in L.color]
        obj["dermis_direction"] = [float(x) for x in L.direction]
        obj["dermis_position"] = [float(x) for x in L.position]
        bpy.context.scene.collection.objects.link(obj)
        objs.append(obj)
    return objs


def build_world(bpy, scene, opts: ExportOptions):
    """Environment light: constant colour or equirect image (same orientation as dermis, see
    convert.EQUIRECT_ROTATION_Z_DEG) times intensity. Camera rays see scene.output.background."""
    env = scene.environment
    world = bpy.data.worlds.new("environment")
    world.use_nodes = True
    nt = world.node_tree
    nodes, links = nt.nodes, nt.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputWorld")
    light_bg = nodes.new("ShaderNodeBackground")
    light_bg.inputs["Strength"].default_value = float(env.intensity)
    if env.image is not None:
        tex = nodes.new("ShaderNodeTexEnvironment")
        tex.image = _load_image(bpy, _image_path(env.image, "environment", opts), _linear_space(bpy))
        tex.projection = "EQUIRECTANGULAR"
        coord = nodes.new("ShaderNodeTexCoord")
        mapping = nodes.new("ShaderNodeMapping")
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(convert.equirect_mapping_z_deg(env.rotation_deg)))
        links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
        links.new(tex.outputs["Color"], light_bg.inputs["Color"])
    else:
        light_bg.inputs["Color"].default_value = (*[float(c) for c in env.color], 1.0)
    cam_bg = nodes.new("ShaderNodeBackground")
    cam_bg.inputs["Color"].default_value = (*[float(c) for c in scene.output.background], 1.0)
    path = nodes.new("ShaderNodeLightPath")
    mix = nodes.new("ShaderNodeMixShader")
    links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    links.new(light_bg.outputs["Background"], mix.inputs[1])
    links.new(cam_bg.outputs["Background"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    world["dermis_intensity"] = float(env.intensity)
    world["dermis_color"] = [float(c) for c in env.color]
    bpy.context.scene.world = world
    return world


def build_scene(scene, opts: ExportOptions | None = None, size=(512, 512)):
    """Replace the current Blender session's data with ``scene``; returns the bpy scene."""
    if getattr(scene, "surfaces", None):  # issue 17: not exported yet; an image without them would be wrong
        raise DermisError(f"{scene.source}: export to Blender does not support non-skin glTF primitives "
                          f"(metallic-roughness materials: {', '.join(s.material.name for s in scene.surfaces)})")
    bpy = require_bpy()
    opts = opts or ExportOptions()
    with quiet_fds():
        bpy.ops.wm.read_factory_settings(use_empty=True)
    bsc = bpy.context.scene
    bsc.name = scene.name or "dermis"
    bsc.unit_settings.system = "METRIC"
    bsc.unit_settings.scale_length = 1.0
    obj = build_mesh(bpy, scene)
    obj.data.materials.append(build_material(bpy, scene, opts))
    build_camera(bpy, scene, size[0] / size[1])
    build_lights(bpy, scene)
    build_world(bpy, scene, opts)
    r = bsc.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y = int(size[0]), int(size[1])
    r.resolution_percentage = 100
    bsc.cycles.device = "CPU"
    bsc.cycles.use_denoising = False
    bsc.cycles.samples = 256
    bsc.cycles.max_bounces = 12
    bsc.cycles.caustics_reflective = bsc.cycles.caustics_refractive = False
    bsc.cycles.sample_clamp_direct = bsc.cycles.sample_clamp_indirect = 0.0
    bsc.view_settings.view_transform = "Standard"
    bsc.view_settings.exposure = float(scene.output.exposure)
    bsc["dermis_mm_per_unit"] = float(scene.mm_per_unit)
    bsc["dermis_source"] = str(scene.source)
    bsc["dermis_sss"] = bool(opts.sss)
    bsc["dermis_specular"] = bool(opts.specular)
    return bsc


def export_blend(scene, path, opts: ExportOptions | None = None, size=(512, 512)) -> Path:
    """Write ``scene`` as a .blend (textures referenced by absolute path; in-memory textures are
    written as EXR beside it). Atomic: the file appears complete or not at all."""
    path = Path(path)
    if path.suffix.lower() != ".blend":
        raise DermisError(f"{path}: the output must be a .blend file")
    if not path.parent.exists():
        raise DermisError(f"{path}: output folder {path.parent} does not exist")
    opts = opts or ExportOptions()
    if opts.texture_dir is None:
        opts.texture_dir = path.parent / f"{path.stem}_textures"
    bpy = require_bpy()
    build_scene(scene, opts, size)
    tmp = path.with_name(f".{path.name}.tmp.blend")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp.resolve()), compress=True, copy=True, relative_remap=False)
    os.replace(tmp, path)
    return path
