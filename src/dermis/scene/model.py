"""The scene model: mesh, skin material, lights, camera, environment, with explicit units.

Conventions (used everywhere in dermis):
- Positions are in scene units; ``Scene.mm_per_unit`` converts them to millimetres, the unit of
  every scattering distance (profiles, blur widths, translucency).
- UVs are OpenGL style: v = 0 is the BOTTOM row of a texture image. Image arrays are stored
  with row 0 at the TOP (as files are) and flipped on upload. Loaders convert other conventions.
- Colours and radiance are linear RGB. sRGB images are decoded to linear on load.
- Tangents are (x, y, z, w) with w = handedness: bitangent = w * cross(N, T) (MikkTSpace).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dermis.errors import DermisError
from dermis.profiles.gaussians import SumOfGaussians, deon_skin


@dataclass
class Mesh:
    positions: np.ndarray  # (N, 3) float32, scene units
    normals: np.ndarray  # (N, 3) float32, unit
    uvs: np.ndarray  # (N, 2) float32, v up
    indices: np.ndarray  # (M, 3) uint32, counter-clockwise from outside
    tangents: np.ndarray | None = None  # (N, 4) float32, w = handedness
    source: str = "<mesh>"
    # the unique UV set texture-space diffusion works in (N, 2), v up; None: ``uvs`` serve
    # (dermis.geometry.texture_space). "auto" | "mesh" | "generate": how it is chosen.
    texture_space_uvs: np.ndarray | None = None
    texture_space_uv: str = "auto"
    # a second UV set (glTF TEXCOORD_1, v up), for maps whose Texture.texcoord is 1; None: absent
    uvs1: np.ndarray | None = None

    def validate(self) -> "Mesh":
        n = len(self.positions)
        if n == 0 or len(self.indices) == 0:
            raise DermisError(f"{self.source}: mesh has no triangles")
        for name in ("positions", "normals", "uvs", "texture_space_uvs", "uvs1"):
            a = getattr(self, name)
            if a is None and name in ("texture_space_uvs", "uvs1"):
                continue
            if a is None:
                raise DermisError(f"{self.source}: mesh has no {name}" + (" (texture coordinates are required)" if name == "uvs" else ""))
            if len(a) != n:
                raise DermisError(f"{self.source}: mesh {name} count {len(a)} != vertex count {n}")
            if not np.all(np.isfinite(a)):
                raise DermisError(f"{self.source}: mesh {name} contain NaN or infinite values")
        if self.indices.min() < 0 or self.indices.max() >= n:
            raise DermisError(f"{self.source}: mesh indices out of range")
        return self

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of the positions per axis; remembered while the positions' content is
        unchanged (dermis.invalidation.memo_by_content: the renderer asks several times a frame)."""
        from dermis.invalidation import memo_by_content

        p = self.positions
        lo, hi = memo_by_content("Mesh.bounds", (p,), (), lambda: (p.min(axis=0), p.max(axis=0)))
        return lo.copy(), hi.copy()


@dataclass
class Texture:
    """An image held in memory: float32 (H, W, C), linear unless it is data (normals, masks)."""

    data: np.ndarray
    source: str = "<texture>"
    # sampler state on upload, per axis (s = u, t = v): "clamp" or "repeat" (a glTF
    # MIRRORED_REPEAT is baked into the image by the loader); filters: (min, mag) as GL enums
    # (glTF sampler minFilter/magFilter), None = trilinear with mipmaps
    wrap: tuple = ("clamp", "clamp")
    filters: tuple | None = None
    # how the map is addressed: the UV set it reads (0 = Mesh.uvs, 1 = Mesh.uvs1) and a 3x3 affine
    # transform of that set's (u, v, 1), v up (KHR_texture_transform, converted by the loader);
    # None = identity. Applied per map in the shaders (common/surface.glsl, map_uv).
    texcoord: int = 0
    transform: np.ndarray | None = None

    def uv_matrix(self) -> np.ndarray:
        """The 3x3 UV transform (float32), identity when there is none."""
        return np.eye(3, dtype=np.float32) if self.transform is None else np.asarray(self.transform, np.float32)

    def mapped_uvs(self, mesh: "Mesh") -> np.ndarray:
        """The (N, 2) coordinates this map is sampled at on ``mesh``'s vertices (affine, so exact
        per vertex: the transform commutes with interpolation)."""
        uv = mesh.uvs1 if self.texcoord == 1 else mesh.uvs
        if uv is None:
            raise DermisError(f"{self.source}: the map reads TEXCOORD_{self.texcoord}, which {mesh.source} does not have")
        T = self.uv_matrix().astype(np.float64)
        return (np.asarray(uv, np.float64) @ T[:2, :2].T + T[:2, 2]).astype(np.float32)

    @property
    def size(self) -> tuple[int, int]:
        return self.data.shape[1], self.data.shape[0]


@dataclass
class SkinMaterial:
    albedo: Texture | None = None  # linear RGB; None = albedo_color
    albedo_color: tuple = (0.62, 0.42, 0.33)  # linear RGB when there is no map
    normal_map: Texture | None = None  # tangent space, OpenGL (+y = +v), encoded n*0.5+0.5
    normal_strength: float = 1.0
    specular_map: Texture | None = None  # intensity in [0,1] scaling rho_s
    roughness: float = 0.3  # Beckmann m (d'Eon 2007: 0.3 for skin)
    roughness_map: Texture | None = None  # Beckmann m per texel (linear data); overrides roughness
    rho_s: float = 0.18  # specular intensity (d'Eon 2007)
    # rho_s at a texel = rho_s * (specular_map_bias + specular_map_scale * map): the seed used
    # 0.18 + 0.16 * spec, i.e. bias 1.0, scale 0.89 with rho_s = 0.18.
    specular_map_bias: float = 1.0
    specular_map_scale: float = 0.89
    mix: float = 0.5  # albedo^mix before scattering, albedo^(1-mix) after (d'Eon 2007 sec 14.5.2)
    pore_scale_mm: float = 0.5  # spacing of procedural pore-detail normals in the final pass
    pore_strength: float = 0.15  # 0 disables procedural pore detail
    # False: the skin is a closed surface wound counter-clockwise seen from outside (its vertex
    # normals' side), so the screen-space passes skip its back faces (glTF 2.0, 3.9.6
    # doubleSided). A rasteriser shades a back face before the front face that hides it is drawn
    # (llvmpipe: the head's final passes took 1.7-2x as long with them); seen from outside they
    # change only a few MSAA samples on silhouettes. True: both faces drawn (an open sheet seen
    # from behind, a mesh wound either way). The shadow pass draws both faces either way.
    double_sided: bool = True


ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")


@dataclass
class MetallicRoughnessMaterial:
    """A glTF 2.0 metallic-roughness material (glTF 2.0 spec 3.9.2, BRDF: Appendix B): what dermis
    renders for every primitive that is not skin (eyes, teeth, hair cards, props). Factors are
    linear; a map multiplies its factor. Shaded by shaders/common/metallic_roughness.glsl."""

    name: str = "<material>"
    base_color: tuple = (1.0, 1.0, 1.0, 1.0)  # baseColorFactor, linear RGBA
    base_color_map: Texture | None = None  # RGBA, linear (sRGB decoded on load), alpha = coverage
    metallic: float = 1.0
    roughness: float = 1.0  # perceptual roughness; GGX alpha = roughness^2
    metallic_roughness_map: Texture | None = None  # G = roughness, B = metallic (linear data)
    normal_map: Texture | None = None  # tangent space, encoded n*0.5+0.5
    normal_scale: float = 1.0
    occlusion_map: Texture | None = None  # R = ambient occlusion (applied to ambient light only)
    occlusion_strength: float = 1.0
    emissive: tuple = (0.0, 0.0, 0.0)  # emissiveFactor, linear RGB radiance
    emissive_map: Texture | None = None
    alpha_mode: str = "OPAQUE"  # OPAQUE | MASK (BLEND is loaded as MASK at alpha_cutoff, with a warning)
    alpha_cutoff: float = 0.5
    double_sided: bool = False

    def maps(self) -> dict:
        return {"base_color": self.base_color_map, "metallic_roughness": self.metallic_roughness_map,
                "normal": self.normal_map, "occlusion": self.occlusion_map, "emissive": self.emissive_map}


@dataclass
class Surface:
    """Geometry that is not skin, with its metallic-roughness material: drawn beside the skin by
    every technique, lit and shadowed by the same lights, never part of the scattering passes."""

    mesh: Mesh
    material: MetallicRoughnessMaterial = field(default_factory=MetallicRoughnessMaterial)


@dataclass
class Light:
    kind: str = "directional"  # directional | point | spot
    color: tuple = (1.0, 1.0, 1.0)  # linear RGB
    intensity: float = 3.0  # irradiance (directional, W/m^2-like units) or intensity (point/spot, per sr)
    direction: tuple = (0.0, 0.0, -1.0)  # direction the light TRAVELS (directional, spot)
    position: tuple = (0.0, 0.0, 10.0)  # scene units (point, spot)
    spot_angle_deg: float = 30.0  # half-angle of the full cone (spot)
    spot_blend: float = 0.15  # fraction of the cone that fades out
    cast_shadows: bool = True
    shadow_softness: float = 1.5  # PCF kernel radius in shadow-map texels
    shadow_bias: float = 0.0015

    def radiance_rgb(self) -> np.ndarray:
        return np.asarray(self.color, np.float32) * np.float32(self.intensity)


@dataclass
class Camera:
    position: tuple = (0.0, 0.0, 10.0)
    target: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov_deg: float = 30.0  # vertical field of view
    near: float | None = None  # None: derived from the scene bounds
    far: float | None = None
    fit: bool = False  # True: moved along and across its direction to fit the mesh (dermis.framing)


@dataclass
class Environment:
    """Ambient light: a constant linear colour, or an equirectangular HDR image."""

    color: tuple = (0.03, 0.03, 0.035)
    image: Texture | None = None  # linear equirect; projected to 9 SH coefficients
    intensity: float = 1.0
    occlusion: bool = True  # the mesh occludes its environment light (geometry/visibility.py)
    rotation_deg: float = 0.0  # the image turned about +y (dermis.environment.rotate_equirect); TOML "rotation"


@dataclass
class Output:
    exposure: float = 0.0  # stops
    tonemap: str = "aces"  # aces | linear
    background: tuple = (0.02, 0.02, 0.025)  # linear RGB
    bloom: float = 0.0  # fraction of the image's energy spread by bloom (0 = off)
    bloom_radius: float = 0.015  # bloom Gaussian's standard deviation, fraction of image height


SKIN_COLORS = ("albedo", "profile")
"""Scene.skin_color: where the skin's total diffuse colour comes from (see Scene)."""


def mean_skin_albedo(material) -> np.ndarray:
    """The albedo map's mean over the skin (every 4th texel, texels whose mean is above 2%: the
    background of a UV layout is not skin), or the constant albedo colour. One definition for the
    real-time techniques, the offline reference and the Blender export."""
    if material.albedo is None:
        return np.asarray(material.albedo_color, np.float64)
    from dermis.images import as_rgb

    a = as_rgb(material.albedo.data[::4, ::4]).reshape(-1, 3).astype(np.float64)
    a = a[a.mean(axis=1) > 0.02]
    return a.mean(axis=0) if len(a) else np.ones(3)


def skin_albedo_scale(scene, albedo_mean=None) -> np.ndarray:
    """The factor on the skin's albedo: 1, or with ``skin_color = "profile"`` the profile's total
    diffuse reflectance over the albedo's mean (:func:`mean_skin_albedo`), so that the skin's mean
    colour is the profile's and the map keeps only its variation."""
    if getattr(scene, "skin_color", "albedo") != "profile":
        return np.ones(3)
    mean = mean_skin_albedo(scene.material) if albedo_mean is None else albedo_mean
    return np.asarray(scene.profile.total_reflectance, np.float64) / np.maximum(mean, 1e-4)


@dataclass
class Scene:
    mesh: Mesh
    material: SkinMaterial = field(default_factory=SkinMaterial)
    lights: list = field(default_factory=list)
    camera: Camera = field(default_factory=Camera)
    environment: Environment = field(default_factory=Environment)
    output: Output = field(default_factory=Output)
    mm_per_unit: float = 1.0
    profile: SumOfGaussians = field(default_factory=deon_skin)
    technique: str = "tsd"
    # "albedo": the albedo map/colour is the skin colour (profile weights renormalised per channel);
    # "profile": the profile's total diffuse reflectance is, and the map keeps its variation
    skin_color: str = "albedo"
    source: str = "<scene>"
    name: str = "scene"
    surfaces: list = field(default_factory=list)  # Surface: the non-skin primitives (glTF metallic-roughness)
    # one diffuse bounce of light between skin surfaces (every technique: dermis.geometry.interreflection)
    interreflection: bool = True
    # the key light's path through thin parts where the bake along -N finds no far face
    # (dermis.geometry.thickness.light_thickness): a CPU ray cast per key-light turn (about 1-2 s at
    # irradiance 1024 on 2 llvmpipe cores), so off unless asked for (the viewer's light drag)
    translucency_light_path: bool = False
    # the skin's directional albedo (tsd, ssss, preintegrated: dermis.profiles.directional_albedo): light entering or
    # leaving at a shallow angle is absorbed less than head-on, k(mu) = 1 + c(A) (2/3 - mu) at N.L and N.V
    directional_albedo: bool = True

    def bounds(self):
        """Bounds of everything drawn: the skin mesh and the non-skin surfaces."""
        lo, hi = self.mesh.bounds
        for s in self.surfaces:
            slo, shi = s.mesh.bounds
            lo, hi = np.minimum(lo, slo), np.maximum(hi, shi)
        return lo, hi

    def all_positions(self) -> np.ndarray:
        """Every vertex drawn (skin first), e.g. to fit shadow maps around."""
        if not self.surfaces:
            return self.mesh.positions
        return np.concatenate([self.mesh.positions] + [s.mesh.positions for s in self.surfaces])
