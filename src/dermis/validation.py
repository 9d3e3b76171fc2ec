"""Argument and scene checks at the API's entry (Renderer, render): every value a user can get
wrong is refused up front with one line in the API's own words (``irradiance_size``, ``size``,
``technique``); the CLI maps those names to its flags (dermis.cli.FLAG_FOR_OPTION).

Ranges are chosen so that nothing downstream overflows float32 (3.4e38) or the frame buffer's half
floats (65504, checked after the frame as well) and no projection divides by zero.
"""

from __future__ import annotations

import math
import numbers
import operator
import threading

import numpy as np

from dermis.camera import FOV_MAX_DEG, FOV_MIN_DEG
from dermis.errors import DermisError

MAX_SIZE = 8192  # output, texture-space and shadow-map resolutions (GL_MAX_TEXTURE_SIZE class)
IRRADIANCE_SIZES = (64, MAX_SIZE)
SHADOW_SIZES = (128, 16384)  # per-light tile; the atlas of all lights is checked against the GPU (gl/shadows.py)
MAX_SAMPLES = 64
EXPOSURE_STOPS = (-64.0, 64.0)  # 2**64 x a half-float radiance stays finite in float32
MAX_INTENSITY = 1e12  # light intensities and environment radiance; far above any scene (sun ~1e3)
MAX_MM_PER_UNIT = 1e6  # 1 km per scene unit
MIN_MM_PER_UNIT = 1e-6  # 1 nm per scene unit: far below skin's structure; smaller underflows the stretch
MAX_COORDINATE = 1e9  # |position| in scene units; float32 keeps ~7 digits
FRAMEBUFFER_MAX = 65504.0  # the largest half float: the frame buffer's format


def check_int(value, name: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise DermisError(f"{name}: must be an integer in [{lo}, {hi}], got {value!r}")
    if not lo <= int(value) <= hi:
        raise DermisError(f"{name}: must be in [{lo}, {hi}], got {value}")
    return int(value)


def check_size(size, name: str = "size") -> tuple[int, int]:
    """(width, height), each an integer in [1, MAX_SIZE]."""
    if isinstance(size, (str, bytes)) or not hasattr(size, "__len__") or len(size) != 2:
        raise DermisError(f"{name}: size must be two integers (width, height), got {size!r}")
    w, h = size
    for v in (w, h):
        if isinstance(v, bool) or not isinstance(v, numbers.Integral):
            raise DermisError(f"{name}: size must be two integers (width, height), got {size!r}")
    w, h = int(w), int(h)
    if w < 1 or h < 1:
        raise DermisError(f"{name}: size {w}x{h} must be at least 1x1")
    if w > MAX_SIZE or h > MAX_SIZE:
        raise DermisError(f"{name}: size {w}x{h} exceeds the limit of {MAX_SIZE}x{MAX_SIZE}")
    return w, h


def check_renderer_options(size, samples, shadow_size, irradiance_size, device):
    """The Renderer's constructor arguments (dermis.renderer.Renderer)."""
    check_size(size)
    check_int(samples, "samples", 0, MAX_SAMPLES)
    check_int(shadow_size, "shadow_size", *SHADOW_SIZES)
    check_int(irradiance_size, "irradiance_size", *IRRADIANCE_SIZES)
    if device is not None:
        check_int(device, "device", 0, 1024)


def check_technique_arg(technique):
    """A technique argument's type (its name is checked by dermis.techniques.technique_class)."""
    if technique is not None and not isinstance(technique, str):
        raise DermisError(f"technique: must be a technique name (str), got {technique!r}")


def check_exposure(value, name: str = "exposure") -> float:
    lo, hi = EXPOSURE_STOPS
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value) or not lo <= value <= hi:
        raise DermisError(f"{name}: must be a finite number of stops in [{lo:g}, {hi:g}], got {value!r}")
    return float(value)


def _vec(value, where, n=3, lo=-math.inf, hi=math.inf):
    if type(value) in (tuple, list) and len(value) == n and all(_plain(x) for x in value):
        # plain floats (what scene files and the viewer give): the same checks without numpy (per frame)
        if all(math.isfinite(x) and lo <= x <= hi for x in value):
            return np.array(value, np.float64)
    try:
        a = np.asarray(value, np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise DermisError(f"{where} must be {n} finite numbers, got {value!r}") from None
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise DermisError(f"{where} must be {n} finite numbers, got {value!r}")
    if np.any(a < lo) or np.any(a > hi):
        raise DermisError(f"{where} must be in [{lo:g}, {hi:g}], got {value!r}")
    return a


def _plain(x) -> bool:
    """A float, or an int that float() takes exactly: checked without numpy or ABCs (per frame)."""
    t = type(x)
    return t is float or t is np.float64 or (t is int and -2 ** 53 <= x <= 2 ** 53)


def _num(value, where, lo, hi, lo_open=False):
    if _plain(value) and math.isfinite(value) and lo <= value <= hi and not (lo_open and value == lo):
        return float(value)
    try:
        finite = math.isfinite(value)
    except (OverflowError, TypeError):  # an int beyond float's range (10 ** 400), not a number
        finite = False
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not finite:
        raise DermisError(f"{where} must be a finite number, got {value!r}")
    if value < lo or (lo_open and value == lo) or value > hi:
        raise DermisError(f"{where} must be in {'(' if lo_open else '['}{lo:g}, {hi:g}], got {value!r}")
    return float(value)


def _texture_values(tex, where, lo=0.0, hi=MAX_INTENSITY):
    if tex is None:
        return
    d = np.asarray(tex.data)
    if not np.all(np.isfinite(d)):
        raise DermisError(f"{where} ({tex.source}) contains NaN or infinite values")
    if d.size and (d.min() < lo or d.max() > hi):
        raise DermisError(f"{where} ({tex.source}) values must be in [{lo:g}, {hi:g}], got [{d.min():g}, {d.max():g}]")


def check_render_call(scene, technique, camera=None):
    """Per frame (Renderer.render): the technique argument and the scene's scalar values (cheap:
    lights, camera, material and output numbers; the mesh and textures were checked by set_scene)."""
    check_technique_arg(technique)
    check_scene_per_frame(scene)
    if camera is not None:
        from dermis.camera import check_camera

        lo, hi = scene.bounds()
        centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
        if not _camera_clearly_valid(camera, centre, radius):
            check_camera(camera, "camera", centre, radius)


# ---------------------------------------------------------------------- per-frame fast path
# check_render_call runs every frame. What it checks is snapshotted in parts (the scene less its
# lights and camera; each light; the camera with the bounds it is checked against) as plain numbers
# and tuples of them, copied. A part that passed its check is remembered: a frame whose parts equal
# validated ones skips their checks (a camera-only frame checks the camera alone, a frame whose
# lights moved those lights). A value that is not a plain number (an array) makes its part
# unsnapshottable, checked every frame; a NaN equals nothing, so it is never taken for validated.
_VALID_KEEP = 256
_VALID_LOCK = threading.Lock()
_VALID: dict = {}  # snapshot -> True, oldest first (the viewer's worker threads validate too)


class _Unfrozen(Exception):
    pass


_SCALARS = frozenset({float, int, str, np.float64, type(None)})
_NUMBERS = frozenset({float, int, np.float64})


def _frozen(v):
    """``v`` as an immutable value for a snapshot: a number, string or None as it is, a tuple or
    list of numbers as a tuple; a bool tagged (True == 1.0, but only one of them is valid where a
    number is asked for); anything else raises _Unfrozen."""
    t = type(v)
    if t in _SCALARS:
        return v
    if (t is tuple or t is list) and set(map(type, v)) <= _NUMBERS:
        return tuple(v)
    if t is bool:
        return ("bool", v)
    raise _Unfrozen


def _frozen_all(values: tuple) -> tuple:
    """A tuple of attribute values as a snapshot (all plain scalars: as it is, no call per value)."""
    if set(map(type, values)) <= _SCALARS:
        return values
    return tuple(map(_frozen, values))


_MATERIAL_FIELDS = operator.attrgetter("albedo_color", "roughness", "rho_s", "mix", "normal_strength",
                                       "specular_map_bias", "specular_map_scale", "pore_strength", "pore_scale_mm")
_SURFACE_FIELDS = operator.attrgetter("base_color", "emissive", "metallic", "roughness", "occlusion_strength",
                                      "normal_scale", "alpha_cutoff", "alpha_mode", "double_sided")
_LIGHT_FIELDS = operator.attrgetter("kind", "color", "intensity", "direction", "position", "spot_angle_deg",
                                    "spot_blend", "shadow_softness", "shadow_bias")
_ENV_FIELDS = operator.attrgetter("color", "intensity", "rotation_deg")
_OUTPUT_FIELDS = operator.attrgetter("exposure", "background", "tonemap", "bloom", "bloom_radius")
_CAMERA_FIELDS = operator.attrgetter("position", "target", "up", "fov_deg", "near", "far")


def _snapshots(scene):
    """(rest, lights, camera) snapshots of what check_scene(full=False) reads, or None."""
    from dermis.scene.model import MetallicRoughnessMaterial, Scene, Surface

    if type(scene) is not Scene:
        return None
    surfaces = scene.surfaces
    if type(surfaces) is not list or not all(type(s) is Surface and type(s.material) is MetallicRoughnessMaterial
                                              for s in surfaces):
        return None
    f = _frozen_all
    try:
        rest = ("scene", scene.source, _frozen(scene.mm_per_unit), f(_MATERIAL_FIELDS(scene.material)),
                tuple(f(_SURFACE_FIELDS(s.material)) for s in surfaces), f(_ENV_FIELDS(scene.environment)),
                f(_OUTPUT_FIELDS(scene.output)))
        lights = [("light", f(_LIGHT_FIELDS(L))) for L in scene.lights]
        camera = ("camera", f(_CAMERA_FIELDS(scene.camera)))
    except (_Unfrozen, AttributeError):
        return None
    return rest, lights, camera


def _remember(snapshot):
    with _VALID_LOCK:
        if snapshot not in _VALID:
            while len(_VALID) >= _VALID_KEEP:
                _VALID.pop(next(iter(_VALID)))
            _VALID[snapshot] = True


def check_scene_per_frame(scene):
    """check_scene(scene, full=False), skipping the parts whose values already passed it."""
    from dermis.camera import check_camera

    snaps = _snapshots(scene)
    if snaps is None or snaps[0] not in _VALID:
        check_scene(scene, full=False)
        if snaps is not None:
            for s in (snaps[0], *snaps[1], snaps[2]):
                _remember(s)
        return
    _, lights, camera = snaps
    src = scene.source
    for i, (L, snap) in enumerate(zip(scene.lights, lights)):
        if snap not in _VALID:
            _check_light(L, f"{src}: [[lights]] #{i + 1}")
            _remember(snap)
    lo, hi = scene.bounds()
    camera = camera + (tuple(lo.tolist()), tuple(hi.tolist()))  # the check depends on the bounds too
    if camera not in _VALID:
        centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
        if not _camera_clearly_valid(scene.camera, centre, radius):
            check_camera(scene.camera, f"{src}: [camera]", centre, radius)
        _remember(camera)


def _camera_clearly_valid(camera, centre, radius) -> bool:
    """check_camera's tests in plain floats, for a camera that passes them by a clear margin (else
    the full check decides, and words the error): finite coordinates within range, a view direction,
    an up vector more than 0.08 degree off it, the field of view in range, near/far unset."""
    try:
        vals = [_frozen(getattr(camera, k)) for k in ("position", "target", "up")]
        fov = camera.fov_deg
        if camera.near is not None or camera.far is not None or type(fov) not in (float, int) or not FOV_MIN_DEG <= fov < FOV_MAX_DEG:
            return False
        if not all(type(v) is tuple and len(v) == 3 for v in vals):
            return False
        if not all(math.isfinite(x) and abs(x) <= 1e12 for v in vals for x in v):
            return False
        (px, py, pz), (tx, ty, tz), (ux, uy, uz) = vals
        vx, vy, vz = tx - px, ty - py, tz - pz
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        un = math.sqrt(ux * ux + uy * uy + uz * uz)
        if not vn > 2e-9 * max(abs(px), abs(py), abs(pz), radius, 1e-30) or not un > 0:
            return False
        return abs(vx * ux + vy * uy + vz * uz) / (vn * un) < 1.0 - 1e-6
    except Exception:
        return False


def _skip(*args, **kw):
    pass


def max_abs(values) -> float:
    """max |x| over ``values`` from their min and max (no |x| temporary; 0.0 when empty, NaN or inf as the
    values give them)."""
    a = np.asarray(values)
    return max(abs(float(a.min())), abs(float(a.max()))) if a.size else 0.0


def check_coordinates(positions, source) -> float:
    """The largest |coordinate| of ``positions`` (scene units), refused over MAX_COORDINATE when finite
    (NaN and inf are the finiteness check's). Loaders call it on the file's own numbers (any dtype, no
    copy) before the float32 cast, which would turn 1e300 into inf and the error into "NaN or infinite"."""
    big = max_abs(positions)
    if math.isfinite(big) and big > MAX_COORDINATE:
        raise DermisError(f"{source}: mesh coordinates reach {big:g}, over the limit of {MAX_COORDINATE:g} units")
    return big


def check_mesh(mesh):
    """Finite values, indices in range (Mesh.validate), coordinates in range, non-zero extent."""
    mesh.validate()
    p = np.asarray(mesh.positions, np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    big = check_coordinates(p, mesh.source)
    diag = float(np.linalg.norm(hi - lo))
    if not diag > 1e-6 * max(big, 1e-30):  # all vertices at (float32-)one point
        raise DermisError(f"{mesh.source}: mesh has zero extent (all vertices at one point)")
    if not _has_area(p, np.asarray(mesh.indices).reshape(-1, 3), 1e-12 * diag * diag):
        # every triangle a line or a point: nothing to shade
        raise DermisError(f"{mesh.source}: mesh has no triangle of non-zero area (all lie on lines or points)")


def _has_area(p, tris, min_twice_area: float, block: int = 1 << 16) -> bool:
    """Whether any triangle of ``tris`` (indices into ``p``) has twice its area above ``min_twice_area``:
    in blocks, stopping at the first that has one (a real mesh's first block), so a 12-million-triangle
    mesh costs one block, not a (n, 3, 3) float64 copy of its corners."""
    for s in range(0, len(tris), block):
        t = p[tris[s:s + block]]
        if np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).max() > min_twice_area:
            return True
    return False


def _check_surfaces(scene, full: bool):
    """The non-skin surfaces (dermis.scene.model.Surface): meshes, and the factors glTF bounds."""
    from dermis.scene.model import ALPHA_MODES, MetallicRoughnessMaterial, Surface

    surfaces = getattr(scene, "surfaces", [])
    if not isinstance(surfaces, list) or not all(isinstance(s, Surface) and isinstance(s.material, MetallicRoughnessMaterial)
                                                 for s in surfaces):
        raise DermisError(f"{scene.source}: scene surfaces must be a list of dermis Surface (mesh + "
                          f"MetallicRoughnessMaterial)")
    for s in surfaces:
        m, w = s.material, f"{scene.source}: material {s.material.name}"
        if full:
            check_mesh(s.mesh)
        _vec(m.base_color, f"{w} baseColorFactor", 4, 0.0, 1.0)
        _vec(m.emissive, f"{w} emissiveFactor", 3, 0.0, MAX_INTENSITY)
        for k in ("metallic", "roughness", "occlusion_strength"):
            _num(getattr(m, k), f"{w} {k}", 0.0, 1.0)
        _num(m.normal_scale, f"{w} normal_scale", -1e3, 1e3)
        _num(m.alpha_cutoff, f"{w} alpha_cutoff", 0.0, 1e3)
        if m.alpha_mode not in ALPHA_MODES[:2]:
            raise DermisError(f"{w} alpha_mode must be OPAQUE or MASK, got {m.alpha_mode!r}")
        if m.double_sided not in (True, False):
            raise DermisError(f"{w} double_sided must be true or false, got {m.double_sided!r}")


def _check_light(L, w: str):
    if L.kind not in ("directional", "point", "spot"):
        raise DermisError(f"{w} type must be directional, point or spot, got {L.kind!r}")
    _vec(L.color, f"{w} color", 3, 0.0, MAX_INTENSITY)
    _num(L.intensity, f"{w} intensity", 0.0, MAX_INTENSITY)
    d = _vec(L.direction, f"{w} direction")
    if np.linalg.norm(d) < 1e-9:
        raise DermisError(f"{w} direction must not be zero")
    _vec(L.position, f"{w} position", 3, -MAX_COORDINATE, MAX_COORDINATE)
    _num(L.spot_angle_deg, f"{w} spot_angle_deg", 0.0, 89.0, lo_open=True)
    _num(L.spot_blend, f"{w} spot_blend", 0.0, 1.0)
    _num(L.shadow_softness, f"{w} shadow_softness", 0.0, 64.0)
    _num(L.shadow_bias, f"{w} shadow_bias", -1.0, 1.0)


def check_scene(scene, full: bool = True):
    """Every value of a Scene that can break a render: names the scene's source and the key in the
    scene file's words ([camera] near, [[lights]] #2 intensity, ...). ``full``: also the mesh and
    the textures' values (O(size); once per scene)."""
    from dermis.camera import check_camera
    from dermis.scene.model import Scene

    if not isinstance(scene, Scene):
        raise DermisError(f"scene: must be a dermis Scene (from dermis.load_scene or dermis.default_scene), "
                          f"got {type(scene).__name__}")
    src = scene.source
    if full:
        check_mesh(scene.mesh)
    _check_surfaces(scene, full)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    diag = float(np.linalg.norm(hi - lo))
    _num(scene.mm_per_unit, f"{src}: [scene] mm_per_unit", MIN_MM_PER_UNIT, MAX_MM_PER_UNIT)
    m = scene.material
    _vec(m.albedo_color, f"{src}: [material] albedo_color", 3, 0.0, 1.0)
    tv = _texture_values if full else _skip  # textures: checked once, by set_scene
    tv(m.albedo, f"{src}: [material] albedo", 0.0, 1.0)
    tv(m.normal_map, f"{src}: [material] normal_map", -1.0, 1.0)
    tv(m.specular_map, f"{src}: [material] specular_map", 0.0, 16.0)
    tv(m.roughness_map, f"{src}: [material] roughness_map", 0.0, 1.0)
    _num(m.roughness, f"{src}: [material] roughness", 0.0, 1.0, lo_open=True)
    _num(m.rho_s, f"{src}: [material] rho_s", 0.0, 1.0)
    _num(m.mix, f"{src}: [material] mix", 0.0, 1.0)
    for k in ("normal_strength", "specular_map_bias", "specular_map_scale", "pore_strength"):
        _num(getattr(m, k), f"{src}: [material] {k}", -1e3, 1e3)
    _num(m.pore_scale_mm, f"{src}: [material] pore_scale_mm", 0.0, 1e6, lo_open=True)
    if m.double_sided not in (True, False):
        raise DermisError(f"{src}: [material] double_sided must be true or false, got {m.double_sided!r}")
    if getattr(scene, "interreflection", True) not in (True, False):
        raise DermisError(f"{src}: [scene] interreflection must be true or false, got {scene.interreflection!r}")
    if getattr(scene, "translucency_light_path", False) not in (True, False):
        raise DermisError(f"{src}: [scene] translucency_light_path must be true or false, "
                          f"got {scene.translucency_light_path!r}")
    if getattr(scene, "directional_albedo", True) not in (True, False):
        raise DermisError(f"{src}: [scene] directional_albedo must be true or false, got {scene.directional_albedo!r}")
    for i, L in enumerate(scene.lights):
        _check_light(L, f"{src}: [[lights]] #{i + 1}")
    check_camera(scene.camera, f"{src}: [camera]", (lo + hi) / 2, diag / 2)
    env = scene.environment
    _vec(env.color, f"{src}: [environment] color", 3, 0.0, MAX_INTENSITY)
    _num(env.intensity, f"{src}: [environment] intensity", 0.0, MAX_INTENSITY)
    tv(env.image, f"{src}: [environment] image", 0.0, MAX_INTENSITY)
    _num(env.rotation_deg, f"{src}: [environment] rotation", -3600.0, 3600.0)
    o = scene.output
    check_exposure(o.exposure, f"{src}: [output] exposure")
    _vec(o.background, f"{src}: [output] background", 3, 0.0, FRAMEBUFFER_MAX)
    if o.tonemap not in ("aces", "linear"):
        raise DermisError(f"{src}: [output] tonemap must be aces or linear, got {o.tonemap!r}")
    _num(o.bloom, f"{src}: [output] bloom", 0.0, 1.0)
    _num(o.bloom_radius, f"{src}: [output] bloom_radius", 0.0, 0.5, lo_open=True)


def check_rendered(img, scene, technique: str):
    """Never hand back NaN or infinity: a frame that overflowed is the scene's fault."""
    if not np.all(np.isfinite(img)):
        raise DermisError(f"{scene.source}: technique '{technique}' produced NaN or infinite radiance (over the frame "
                          f"buffer's half-float range of {FRAMEBUFFER_MAX:g}?): lower the light or environment intensities")
