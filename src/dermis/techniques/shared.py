"""The shading contract every technique shares, owned here and nowhere else.

Python side: the limits (lights, Gaussians), the output modes, the texture unit of every shared
sampler, the translucency threshold, the profile and translucency uniforms, the sampler binding
helper and the specular tables (uploaded once per Renderer). GLSL side: ``common/constants.glsl``
is GENERATED from these constants when a shader is loaded (:func:`glsl_constants`, wired in
dermis.gl.shaders), so no shader repeats a number that Python also holds.

Radiometric convention (the one statement of it; README, dermis.specular and the shaders refer
here): dermis renders PHYSICAL linear radiance. A Lambertian surface of albedo a under irradiance E
leaves radiance a E / pi. d'Eon & Luebke's specular formulas (GPU Gems 3, ch. 14) carry no 1/pi
(their Beckmann P integrates to pi against N.h), so every skin shader divides their specular,
and the specular albedo a(cos, m) of :func:`dermis.specular.rho_dt_table`, by pi:
    diffuse  = albedo * E / pi * (1 - rho_s a(N.V, m) / pi)
    specular = sum_lights E_i * KS_Skin_Specular / pi,    energy left: 1 - rho_s a(cos, m) / pi.
The skin techniques (tsd, ssss, preintegrated) weight each light by the skin's directional albedo
k(N.L) and the reflected scattered light by k(N.V) (dermis.profiles.directional_albedo,
shaders/common/directional_albedo.glsl; the ambient enters at k = 1, the light through thin parts
leaves Lambertian), switched by ``[scene] directional_albedo`` (:func:`directional_albedo_uniforms`).

No technique imports another: what two of them share lives here or in shaders/common/.
GL objects are imported inside the helpers, so dermis.gl may import these constants.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from dermis.errors import DermisError
from dermis.prefiltered_environment import LAYERS as ENV_SPECULAR_LAYERS, SKIN_ENV_GRAZING_EXPONENT
from dermis.specular import M_MAX, M_MIN, SKIN_F0, TABLE_ATLAS

MAX_LIGHTS = 8
"""Lights a scene may hold: the size of the light arrays in common/lights.glsl."""

MAX_GAUSSIANS = 8
"""Gaussians a profile may hold on the GPU (ssss's horizontal pass writes one target per Gaussian,
and GL guarantees 8 draw buffers)."""

TRANSLUCENCY_MIN_VARIANCE_MM2 = 0.15
"""Gaussians at least this wide (mm^2) carry light through thin parts; d'Eon uses Gaussians 3..6 of
the skin table (v >= 0.187), the narrow ones carry nothing through millimetres of tissue."""

TISSUE_TAU = 0.25
"""Light travels between two surface points inside the tissue only: a pair whose straight segment
leaves either point into the air more than asin(TISSUE_TAU) = 14.5 degrees above its (facet's)
tangent plane exchanges light along the path round the concave bend between them, or none where no
single bend joins them (a crease, a step): dermis.reference.integrate._tissue_path (paths =
"tissue") and ssss's blurs (ssss/kernel.glsl, ssss_tissue_path). The same tau bounds how far the
two facets may depart from a wedge."""

INV_PI = 1.0 / math.pi

LIGHT_TYPES = {"directional": 0, "point": 1, "spot": 2}
"""Light kind -> the integer in uLightPosType.w (LIGHT_DIRECTIONAL etc. in GLSL)."""


class OutputMode(IntEnum):
    """What a technique's final pass writes (uOutputMode; OUTPUT_* in GLSL)."""

    FULL = 0  # diffuse + specular
    DIFFUSE = 1  # diffuse only
    SPECULAR = 2  # specular only
    CURVATURE = 3  # preintegrated: the curvature used (1/mm) in every channel


class Unit(IntEnum):
    """Texture units of the shared samplers; a technique's own textures start at FIRST_FREE."""

    SHADOW_ATLAS = 0
    INTERREFLECTION = 1  # the one-bounce irradiance per vertex (common/mesh.vert, bind_interreflection)
    ALBEDO = 2
    NORMAL = 3
    SPECULAR = 4
    ROUGHNESS = 5
    SPECULAR_TABLES = 6  # the Beckmann and rho_dt tables in one texture (dermis.gl.tables)
    ENVIRONMENT_SPECULAR = 7  # the prefiltered environment (dermis.gl.environment)
    FIRST_FREE = 8


SHARED_SAMPLERS = {"uShadowAtlas": Unit.SHADOW_ATLAS, "uAlbedoMap": Unit.ALBEDO,
                   "uNormalMap": Unit.NORMAL, "uSpecularMap": Unit.SPECULAR, "uRoughnessMap": Unit.ROUGHNESS,
                   "uSpecularTables": Unit.SPECULAR_TABLES, "uEnvSpecular": Unit.ENVIRONMENT_SPECULAR}
"""Sampler uniform -> unit, for every sampler the shared GLSL (shaders/common) declares."""

METALLIC_ROUGHNESS_SAMPLERS = {"uBaseColorMap": Unit.ALBEDO, "uNormalMap": Unit.NORMAL,
                               "uMetallicRoughnessMap": Unit.SPECULAR, "uOcclusionMap": Unit.ROUGHNESS,
                               "uEmissiveMap": Unit.SPECULAR_TABLES}
"""Sampler -> unit in the program of non-skin surfaces (shaders/metallic_roughness/, dermis.gl.surfaces):
a separate program, so it reuses the skin material's units (it reads no specular tables) and leaves
FIRST_FREE onwards alone; the shadow atlas and the prefiltered environment keep their units."""

GUARANTEED_TEXTURE_UNITS = 16
"""GL_MAX_TEXTURE_IMAGE_UNITS every GL 4.5 implementation offers per stage."""


PORE_FADE = (0.25, 0.5)
"""The pore detail's first octave fades out as the pixel's footprint grows from PORE_FADE[0] to
PORE_FADE[1] times the pore scale (common/noise.glsl, pore_normal; the second octave at half of
those): from PORE_FADE[1] on it leaves the normal unchanged (:func:`pores_invisible`)."""


def _glsl_float(x: float) -> str:
    return repr(float(x))


def glsl_constants() -> str:
    """The text of shaders/common/constants.glsl, generated from the constants above.
    MAX_GAUSSIANS is guarded: a program may be compiled for exactly a profile's K."""
    lines = ["// GENERATED from dermis/techniques/shared.py when the shader is loaded: edit it there.",
             f"#define MAX_LIGHTS {MAX_LIGHTS}",
             "#ifndef MAX_GAUSSIANS", f"#define MAX_GAUSSIANS {MAX_GAUSSIANS}", "#endif",
             f"const float INV_PI = {_glsl_float(INV_PI)};",
             f"#define DERMIS_SPECULAR_M_MIN {_glsl_float(M_MIN)}",
             f"#define DERMIS_SPECULAR_M_MAX {_glsl_float(M_MAX)}",
             "#ifndef DERMIS_SKIN_F0", f"#define DERMIS_SKIN_F0 {_glsl_float(SKIN_F0)}", "#endif",
             f"#define DERMIS_ENV_SPECULAR_LAYERS {ENV_SPECULAR_LAYERS}",
             f"#define DERMIS_SKIN_ENV_GRAZING_EXPONENT {_glsl_float(SKIN_ENV_GRAZING_EXPONENT)}",
             f"#define DERMIS_PORE_FADE vec2({_glsl_float(PORE_FADE[0])}, {_glsl_float(PORE_FADE[1])})"]
    lines += [f"#define DERMIS_{name.upper()}_RECT vec4({', '.join(_glsl_float(v) for v in rect)})"
              for name, rect in TABLE_ATLAS.items()]
    lines += [f"#define LIGHT_{kind.upper()} {v}" for kind, v in LIGHT_TYPES.items()]
    lines += [f"#define OUTPUT_{m.name} {int(m)}" for m in OutputMode]
    return "\n".join(lines)


# ---------------------------------------------------------------------- binding
def bind_sampler(prog, name: str, tex, unit: int) -> None:
    """Bind ``tex`` to ``unit`` and point sampler ``name`` at it, if the program uses it. The
    texture is bound every time (other passes use the same units); the sampler uniform is written
    only when it changes (dermis.gl.resources.set_uniform)."""
    from dermis.gl.resources import set_uniform, use_texture

    if prog.get(name, None) is not None:
        use_texture(tex, int(unit))
        set_uniform(prog, name, int(unit))


def bind_sampler_array(prog, name: str, textures, first_unit: int) -> None:
    """Bind a sampler array (``uniform sampler2D name[N]``) to consecutive units from first_unit;
    the compiler may trim the array's unused tail, so only its active length is bound."""
    from dermis.gl.resources import set_uniform, use_texture

    u = prog.get(name, None)
    if u is None:
        return
    n = getattr(u, "array_length", 1)
    units = []
    for i, tex in enumerate(list(textures)[:n]):
        use_texture(tex, first_unit + i)
        units.append(first_unit + i)
    set_uniform(prog, name, units if n > 1 else units[0])


def bind_specular_tables(prog, tables: dict) -> None:
    """The Renderer's specular tables (dermis.gl.tables) at their contract unit."""
    bind_sampler(prog, "uSpecularTables", tables["atlas"], Unit.SPECULAR_TABLES)


def bind_environment_specular(prog, texture) -> None:
    """The prefiltered environment (dermis.gl.environment) at its contract unit."""
    bind_sampler(prog, "uEnvSpecular", texture, Unit.ENVIRONMENT_SPECULAR)


# ---------------------------------------------------------------------- uniforms
def set_profile_uniforms(prog, profile, max_gaussians: int = MAX_GAUSSIANS) -> None:
    """The uniforms of shaders/common/profile.glsl: the profile's K variances (mm^2) and its weights
    normalised per channel (sum_k w_k = 1), padded to ``max_gaussians`` (weights 0, variances 1:
    a padded entry adds nothing and never divides by zero)."""
    from dermis.gl.resources import set_uniform
    from dermis.invalidation import memo_by_content, read_only

    K = profile.k
    if K > max_gaussians:
        raise DermisError(f"profile '{profile.name}' has {K} Gaussians; at most {max_gaussians} are supported")

    def arrays():  # per profile content, not per pass
        weights = np.zeros((max_gaussians, 3), np.float32)
        weights[:K] = profile.normalized().weights
        variances = np.ones(max_gaussians, np.float32)
        variances[:K] = profile.variances_mm2
        return read_only(weights), read_only(variances)
    weights, variances = memo_by_content("profile_uniforms", (profile.variances_mm2, profile.weights), max_gaussians,
                                         arrays)
    set_uniform(prog, "uGaussianCount", K)
    for name, arr in (("uWeights", weights), ("uVariances", variances)):
        u = prog.get(name, None)
        if u is not None:  # the compiler may trim an array's unused tail
            set_uniform(prog, name, np.ascontiguousarray(arr[: getattr(u, "array_length", 1)]).tobytes())


def thin_slab_law(scene):
    """The thin-slab law (dermis.profiles.thin_slab) of the scene's profile at its skin's mean
    albedo (dermis.scene.model.mean_skin_albedo times the albedo scale), remembered per content."""
    from dermis.invalidation import memo_by_content
    from dermis.profiles.thin_slab import slab_law
    from dermis.scene.model import mean_skin_albedo, skin_albedo_scale

    mat, prof = scene.material, scene.profile
    colour = mat.albedo.data if mat.albedo is not None else np.asarray(mat.albedo_color, np.float64)

    def compute():
        albedo = np.clip(mean_skin_albedo(mat) * skin_albedo_scale(scene), 1e-4, 0.999)
        return albedo, slab_law(prof, albedo)

    return memo_by_content("thin_slab_law", (colour, prof.weights, prof.variances_mm2),
                           getattr(scene, "skin_color", "albedo"), compute)


def translucency_uniforms(prog, enabled: bool, strength: float = 1.0, scene=None) -> None:
    """Uniforms of the translucency of thin parts (common/transmittance.glsl, tsd/translucency.frag,
    common/thin_slab.glsl: the slab law of ``scene``'s profile and skin)."""
    from dermis.gl.resources import set_uniform

    set_uniform(prog, "uTranslucencyMinVariance", TRANSLUCENCY_MIN_VARIANCE_MM2)
    set_uniform(prog, "uTranslucencyStrength", float(strength) if enabled else 0.0)
    if scene is not None and enabled:
        albedo, law = thin_slab_law(scene)
        for name, value in (("uSlabReducedAlbedo", law.reduced_albedo), ("uSlabKappa", law.kappa_per_mm),
                            ("uSlabSourceDepth", law.source_depth_mm), ("uSlabExtrapolation", law.extrapolation_mm),
                            ("uSlabAlbedo", albedo)):
            set_uniform(prog, name, tuple(float(x) for x in value))


def subsurface_transfer_uniforms(prog, frame, transfer, enabled: bool, unit: int) -> None:
    """The baked subsurface transfer for a screen pass (common/subsurface_transfer.glsl: ssss's final
    pass, preintegrated): the grid ``transfer`` (dermis.gl.subsurface_transfer.SubsurfaceTransfer, the
    technique's own) gathered from the shared rho E where the scene has a bake and ``enabled`` (the
    technique's translucency: tsd adds it only with translucency on too), read at the level tsd's
    translucency target reads at the same irradiance size; else uTransferLevel = -1 (nothing added).
    Call it before the pass's target is bound (a gather draws into the grid)."""
    from dermis.gl.resources import set_uniform

    S = max(int(frame.renderer.irradiance_size) // 2, 1)
    grid = transfer.screen_grid(frame, (S, S)) if enabled else None
    tex, level = grid if grid is not None else (transfer.placeholder, -1)
    bind_sampler(prog, "uTransfer", tex, unit)
    set_uniform(prog, "uTransferLevel", float(level))
    transfer.bind_view(prog, level)  # the view term's images (common/subsurface_transfer.glsl)


def surface_detail_uniforms(prog, material, output_mode: int = OutputMode.FULL) -> None:
    """The final passes' procedural pore detail and output mode."""
    from dermis.gl.resources import set_uniform

    for name, value in (("uPoreScaleMm", float(material.pore_scale_mm)), ("uPoreStrength", float(material.pore_strength)),
                        ("uOutputMode", int(OutputMode(output_mode)))):
        set_uniform(prog, name, value)


# ---------------------------------------------------------------------- programs per light count
LIGHT_COUNT_DEFINE = "SKIN_LIGHT_COUNT"
"""The define that unrolls a shader's light loop (DERMIS_FOR_EACH_LIGHT, common/lights.glsl)."""


def light_signature(lights) -> tuple:
    """Per light (kind, shadow kernel): what a program compiled for the scene's lights may fold at
    compile time (SKIN_LIGHT_KINDS, common/lights.glsl; SKIN_SHADOW_FILTERS, common/shadow.glsl).
    ``lights``: the scene's Light objects (as LightUniforms packs them). The kernel
    is dermis.gl.shadows.pcf_filter's; a light's direction, colour, intensity are not in it: moving or
    recolouring a light keeps its program."""
    from dermis.gl.shadows import pcf_filter

    return tuple((LIGHT_TYPES[L.kind], pcf_filter(L.cast_shadows, L.shadow_softness)) for L in lights)


SIGNATURE_DEFINES = ("SKIN_LIGHT_KINDS", "SKIN_SHADOW_FILTERS")
"""The defines :func:`signature_defines` sets (common/lights.glsl, common/shadow.glsl)."""


def signature_defines(signature: tuple) -> dict:
    """SKIN_LIGHT_KINDS and SKIN_SHADOW_FILTERS for :func:`light_signature`'s tuple (none for 0 lights)."""
    if not signature:
        return {}
    kinds, filters = SIGNATURE_DEFINES
    return {kinds: ", ".join(str(int(k)) for k, _ in signature),
            filters: ", ".join(str(int(f)) for _, f in signature)}


class LightCountPrograms:
    """One shader pair compiled per scene light count, with LIGHT_COUNT_DEFINE = n: its loop over
    the lights (DERMIS_FOR_EACH_LIGHT) written out with constant indices into the light uniforms.
    On llvmpipe that made tsd's irradiance pass 15-30% and lambert's ~20% cheaper than the loop
    over uLightCount, the image the same to float rounding (benchmarks/RESULTS.md, round 9, irr9
    and unroll9). Each count is compiled on first use and kept (a live Renderer switching light
    counts recompiles nothing); :meth:`release` frees them all, with the technique.
    ``defines``: the pair's other defines; ``per_count(n)``: more defines for n lights (or None).
    The pore-free variant (:func:`shading_program`) is compiled from the per-count program's own
    sources, so it is unrolled for the same count.
    ``signature=True``: compiled per :func:`light_signature` too (the lights' kinds and shadow kernels
    as constants: :func:`signature_defines`), called with the scene's lights; the same floats, less
    arithmetic on llvmpipe (tsd's irradiance light pass, round 24, irr24). A light whose kind, shadow
    flag or kernel changes (the viewer's softness across ~1.65 texels) compiles once more (~1 s on llvmpipe)."""

    def __init__(self, ctx, vertex: str, fragment: str, defines: dict | None = None, per_count=None,
                 signature: bool = False):
        self.ctx, self.vertex, self.fragment = ctx, vertex, fragment
        self.defines = dict(defines or {})
        self.per_count = per_count
        self.signature = bool(signature)
        self._programs = {}  # light count (and light_signature) -> program

    def __call__(self, n: int, lights=None):
        """The program for a scene of ``n`` lights (0..MAX_LIGHTS); with ``signature``, ``lights`` (the
        scene's Light objects, n of them) is required."""
        n = int(n)
        if not 0 <= n <= MAX_LIGHTS:
            raise DermisError(f"a scene holds 0 to {MAX_LIGHTS} lights, got {n}")
        sig = None
        if self.signature:
            if lights is None or len(lights) != n:
                raise DermisError(f"programs compiled per light signature need the scene's {n} lights")
            sig = light_signature(lights)
        key = n if sig is None else (n, sig)
        if key not in self._programs:
            from dermis.gl.shaders import program

            defines = {**self.defines, **(self.per_count(n) if self.per_count else {}), LIGHT_COUNT_DEFINE: n,
                       **(signature_defines(sig) if sig else {})}
            self._programs[key] = program(self.ctx, self.vertex, self.fragment, defines)
        return self._programs[key]

    def compile_for(self, scene) -> "LightCountPrograms":
        """Compile ``scene``'s light count now (``scene`` None: nothing), as the techniques compile
        their other programs up front: the first frame, or a technique switched to in the viewer
        mid-drag, does not wait on a compile (~1.3 s for tsd's irradiance program on llvmpipe)."""
        if scene is not None:
            self(len(scene.lights), scene.lights)
        return self

    def values(self):
        return list(self._programs.values())

    def release(self) -> None:
        for p in self._programs.values():
            p.release()
        self._programs = {}


# ---------------------------------------------------------------------- pore detail's program variant
PORES_INVISIBLE_DEFINE = "DERMIS_PORES_INVISIBLE"
PORE_FOOTPRINT_MARGIN = 1.05
""":func:`pores_invisible` asks for a bound this much above the fade's end: the shader's footprint
is a finite difference in fp32 (relative error ~1e-6), the bound exact but for the pixel's
half-texel offsets, which the frustum's extent plus one pixel covers."""


def min_pixel_footprint(frame) -> float:
    """A lower bound, in scene units, on what common/noise.glsl takes as a fragment's footprint,
    max(|dP/dx|, |dP/dy|) (P the world position, one pixel apart), over every fragment of the mesh.

    Orthographic: one pixel spans 2 / (P00 W) along x (2 / (P11 H) along y) at every depth.
    Perspective (view-space ray directions d = (x, y, -1), x = (x_ndc + P02) / P00 per unit depth):
    two rays one pixel apart (s = 2 / (P00 W) in x) make an angle a with
    sin a = |d1 x d2| / (|d1| |d2|) = s sqrt(1 + y^2) / (|d1| |d2|) >= s / (|d1| |d2|); the fragment's
    point on ray 1 at view depth z lies z |d1| from the eye, so any point of ray 2 (its neighbour's,
    on the triangle's plane, helper pixels included) is at least z |d1| sin a >= z s / |d2| away. |d2| is largest at
    the frustum's corners widened by a pixel, and z >= the larger of the near plane (clipping) and
    the nearest vertex's depth (depth is linear over a triangle)."""
    proj = np.asarray(frame.proj, np.float64)
    w, h = frame.size
    sx, sy = 2.0 / (proj[0, 0] * w), 2.0 / (proj[1, 1] * h)
    if proj[3, 3] == 1.0 and proj[3, 2] == 0.0:  # orthographic
        return float(min(sx, sy))
    view = np.asarray(frame.view, np.float64)
    pos = np.asarray(frame.scene.mesh.positions, np.float64)
    depth = -(pos @ view[2, :3] + view[2, 3])
    z = max(float(depth.min()), float(frame.near))
    tx = max(abs(-1.0 + proj[0, 2]), abs(1.0 + proj[0, 2])) / proj[0, 0] + sx
    ty = max(abs(-1.0 + proj[1, 2]), abs(1.0 + proj[1, 2])) / proj[1, 1] + sy
    return float(z * min(sx, sy) / math.sqrt(1.0 + tx * tx + ty * ty))


def pores_invisible(frame) -> bool:
    """True when pore_normal returns the normal unchanged at every fragment of the frame: no pore
    strength, or every footprint (:func:`min_pixel_footprint`, in mm) at or beyond the fade's end."""
    mat = frame.scene.material
    if mat.pore_strength <= 0.0 or mat.pore_scale_mm <= 0.0:
        return True
    footprint_mm = min_pixel_footprint(frame) * frame.scene.mm_per_unit
    return footprint_mm >= PORE_FADE[1] * mat.pore_scale_mm * PORE_FOOTPRINT_MARGIN


def shading_program(frame, prog):
    """The program to draw a screen-space skin pass with: ``prog``, or where :func:`pores_invisible`
    holds and ``prog`` evaluates pore detail, its variant compiled with PORES_INVISIBLE_DEFINE
    (one per program and Renderer, made on first use), with ``prog``'s uniform values copied into it.
    The image is the same (pore_normal returns N either way); a CPU rasteriser saves the noise,
    which it evaluates under the false branch anyway (benchmarks/RESULTS.md, round 9, screen9)."""
    if prog.get("uPoreStrength", None) is None or not pores_invisible(frame):
        return prog
    sources = (prog.extra or {}).get("sources") if isinstance(prog.extra, dict) else None
    if sources is None:  # not made by dermis.gl.shaders.program: nothing to compile a variant from
        return prog
    from dermis.gl.shaders import program

    variants = frame.renderer.program_variants
    entry = variants.get(id(prog))
    if entry is None:  # keyed on the program object, held in the entry: its id cannot be reused while cached
        vertex, fragment, defines, geometry = sources
        entry = variants[id(prog)] = (prog, program(frame.ctx, vertex, fragment, {**defines, PORES_INVISIBLE_DEFINE: None},
                                                     geometry))
    variant = entry[1]
    for name in prog:
        u = prog[name]
        if type(u).__name__ != "Uniform":
            continue
        v = variant.get(name, None)
        if v is None:
            continue
        data = u.read()
        if v.extra != data:  # the variant's uniforms go through here only (set_uniform's cache)
            v.write(data)
            v.extra = data
    return variant


def directional_albedo_uniforms(prog, scene) -> None:
    """``uDirectionalAlbedo``: 1 where the scene asks for the skin's directional albedo (the
    default), 0 for a Lambertian entry and exit (scene.directional_albedo; the offline reference
    comparison turns it off, dermis.reference.validate)."""
    from dermis.gl.resources import set_uniform

    set_uniform(prog, "uDirectionalAlbedo", float(bool(getattr(scene, "directional_albedo", True))))


def casts_translucency(scene) -> bool:
    """Thin parts transmit light only from lights with a shadow (thickness) map."""
    return any(L.cast_shadows for L in scene.lights)


# ---------------------------------------------------------------------- interreflection
INTERREFLECTION_DEFINE = "DERMIS_INTERREFLECTION"
"""The define of the programs that add the one bounce (common/mesh.vert reads E_b per vertex,
common/interreflection.glsl): a technique compiles them beside its plain ones and draws the plain
ones with ``[scene] interreflection = false``, so that turning it off gives the old image bit for bit."""


def interreflection_on(scene) -> bool:
    """Whether the scene asks for one diffuse bounce between skin surfaces (``[scene] interreflection``)."""
    return bool(getattr(scene, "interreflection", True))


def prepare_interreflection(frame) -> bool:
    """Whether the frame's scene has the bounce; if so, the Renderer's shared one-bounce irradiance
    per vertex (dermis.gl.interreflection.SharedBounce) is made current: its passes run only when
    the lights, environment, material or mesh changed (PRODUCTS "interreflection"), never on a
    camera-only frame. Call it before a technique's own passes (it draws into its own targets);
    then :func:`bind_interreflection` in the program compiled with INTERREFLECTION_DEFINE. tsd adds
    its own bounce in texture space and calls neither."""
    if not interreflection_on(frame.scene):
        return False
    frame.renderer.interreflection.get(frame)
    return True


def bind_interreflection(frame, prog) -> None:
    """E_b per mesh vertex (made current by :func:`prepare_interreflection`) at Unit.INTERREFLECTION
    for common/mesh.vert: the uniforms written when the texture or its layout changes, the texture
    bound every frame (dermis.gl.resources.prepared)."""
    from dermis.gl.resources import prepared, set_uniform

    bounce = frame.renderer.interreflection
    tex, per_row = bounce.texture, int(bounce.hits.per_row)

    def setup(p):
        bind_sampler(p, "uBounce", tex, Unit.INTERREFLECTION)
        set_uniform(p, "uVerticesPerRow", per_row)
    prepared(prog, "interreflection", (tex, per_row), setup)
