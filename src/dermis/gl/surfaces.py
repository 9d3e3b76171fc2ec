"""Non-skin surfaces on the GPU: each Surface's (dermis.scene.model) vertex buffer, in the skin
mesh's layout (dermis.gl.resources.VERTEX_FORMAT, with the open sky's visibility), and its glTF
metallic-roughness maps, bound at the units of dermis.techniques.shared.METALLIC_ROUGHNESS_SAMPLERS
for shaders/metallic_roughness/ (shading) and shaders/shadow/occluder.frag (the shadow atlas).
A map the material lacks is a 1x1 white texture (a flat normal for the normal map), so its factor
applies alone (glTF 2.0 3.9.2)."""

from __future__ import annotations

import numpy as np

from dermis.geometry.visibility import open_visibility
from dermis.gl.resources import (interleave, map_uniforms, release_mesh_objects, set_uniform, upload_texture,
                                 vertex_attributes, vertex_content)
from dermis.techniques.shared import METALLIC_ROUGHNESS_SAMPLERS

# map key of MetallicRoughnessMaterial.maps() -> (sampler uniform, uniform prefix, channels, 1x1 default)
_MAPS = {"base_color": ("uBaseColorMap", "BaseColor", 4, (1.0, 1.0, 1.0, 1.0)),
         "metallic_roughness": ("uMetallicRoughnessMap", "MetallicRoughness", 3, (1.0, 1.0, 1.0)),
         "normal": ("uNormalMap", "Normal", 3, (0.5, 0.5, 1.0)),
         "occlusion": ("uOcclusionMap", "Occlusion", 1, (1.0,)),
         "emissive": ("uEmissiveMap", "Emissive", 3, (1.0, 1.0, 1.0))}


class GpuSurface:
    """One non-skin Surface on one context: its vertex and index buffers, its maps, its uniforms."""

    def __init__(self, ctx, surface):
        self.ctx = ctx
        self.surface = surface
        m = surface.mesh
        self.vbo = ctx.buffer(interleave(vertex_attributes(m), open_visibility(len(m.positions), m.normals)))
        self.ibo = ctx.buffer(np.ascontiguousarray(m.indices, np.uint32).tobytes())
        self._vaos = {}
        self.textures = {}
        for key, tex in surface.material.maps().items():
            _, _, c, default = _MAPS[key]
            if tex is None:
                self.textures[key] = upload_texture(ctx, np.array([[default]], np.float32), mipmaps=False)
            else:
                data = np.asarray(tex.data, np.float32)
                if data.shape[2] < c:  # a grey map: replicated (alpha, where asked for, is 1)
                    data = np.concatenate([np.repeat(data[:, :, :1], min(c, 3), axis=2),
                                           np.ones(data.shape[:2] + (c - min(c, 3),), np.float32)], axis=2)
                # normals as 8-bit UNORM like the skin's; colours and data as half floats
                self.textures[key] = upload_texture(ctx, data[:, :, :c], components=c,
                                                    dtype="f1" if key == "normal" else "f2",
                                                    wrap=tex.wrap, filters=tex.filters)

    @property
    def double_sided(self) -> bool:
        return bool(self.surface.material.double_sided)

    def vao(self, prog):
        key = id(prog)  # the program is held in the entry: its id cannot be reused while cached
        if key not in self._vaos:
            self._vaos[key] = (self.ctx.vertex_array(prog, [vertex_content(self.vbo, prog)], self.ibo), prog)
        return self._vaos[key][0]

    def uniforms(self, prog):
        """The material's maps at their units, each map's UV set and transform, and its factors."""
        mat = self.surface.material
        maps = mat.maps()
        for key, (sampler, prefix, _, _) in _MAPS.items():
            if prog.get(sampler, None) is not None:
                unit = int(METALLIC_ROUGHNESS_SAMPLERS[sampler])
                self.textures[key].use(unit)
                set_uniform(prog, sampler, unit)
            map_uniforms(prog, prefix, maps[key])
        set_uniform(prog, "uBaseColorFactor", tuple(float(x) for x in mat.base_color))
        set_uniform(prog, "uMetallicFactor", float(mat.metallic))
        set_uniform(prog, "uRoughnessFactor", float(mat.roughness))
        set_uniform(prog, "uNormalStrength", float(mat.normal_scale))
        set_uniform(prog, "uOcclusionStrength", float(mat.occlusion_strength))
        set_uniform(prog, "uEmissiveFactor", tuple(float(x) for x in mat.emissive))
        set_uniform(prog, "uAlphaCutoff", float(mat.alpha_cutoff) if mat.alpha_mode == "MASK" else -1.0)

    def release(self):
        release_mesh_objects(self)
