"""The viewer's live parameters and how they reach the Scene.

:class:`ViewerParams` is everything the panel (or a script) can change. :class:`SceneEditor`
writes it into the Scene that the Renderer draws; the Renderer notices through its lighting key
(material, lights, environment, profile), so only what changed re-runs. Skin profiles from
physics take about a second to compute, so :class:`SkinProfileWorker` computes them off the
render thread and the viewer swaps the result in when it is ready.

Skin colour from the physical model: a diffusion profile's total reflectance R_d (the sum of
its Gaussians' weights, per channel) is the skin's diffuse colour. With ``skin_color =
"profile"`` (the scene model's ``Scene.skin_color``, the default for spectral profiles as in a
scene file's [skin] section) the renderer scales the albedo map so that its mean is R_d: the map
keeps its variation (lips, freckles, stubble), the spectral model (Donner & Jensen 2006:
melanin, melanin blend, haemoglobin, oxygenation, epidermis thickness) sets the colour, and more
melanin darkens the skin. ``"albedo"`` keeps the map's own colour.
"""

from __future__ import annotations

import concurrent.futures
import copy
import dataclasses
from dataclasses import dataclass

import numpy as np

from dermis.errors import DermisError
from dermis.output import TONEMAPS
from dermis.profiles.presets import PRESETS
from dermis.scene.model import SKIN_COLORS

# "scene" keeps the scene's own profile; then every preset; "physical" uses the sliders
PROFILES = ("scene",) + PRESETS + ("physical",)
ENVIRONMENTS = ("scene", "constant", "off")
IRRADIANCE_SIZES = (128, 256, 512, 1024, 2048)
BUFFER_SCALES = ("auto", "exposure")


@dataclass
class ViewerParams:
    """Everything the viewer's panel and scripts change live (names double as script keys)."""

    technique: str = "tsd"
    # skin profile: "scene" keeps the scene's own; presets; "physical" uses the sliders
    profile: str = "scene"
    melanin: float = 0.005  # C_m, melanin volume fraction in the epidermis
    melanin_blend: float = 0.7  # beta_m, eumelanin share of the melanin
    hemoglobin: float = 0.005  # C_h, blood volume fraction in the dermis
    oxygenation: float = 0.75  # oxy-haemoglobin share of the blood
    epidermis_mm: float = 0.25  # epidermis thickness, mm
    skin_color: str = "profile"  # spectral profiles: "profile" colours the skin with R_d, "albedo" keeps the map
    # material
    mix: float = 0.5
    roughness: float = 0.3
    rho_s: float = 0.18
    # the light the panel and right-drag edit
    light_index: int = 0
    light_color: tuple = (1.0, 1.0, 1.0)
    light_intensity: float = 3.0
    # environment
    environment: str = "scene"
    environment_color: tuple = (0.03, 0.03, 0.035)
    environment_intensity: float = 1.0
    # output
    exposure: float = 0.0
    tonemap: str = "aces"
    irradiance_size: int = 512
    # what the window shows: "final" or the name of an intermediate buffer
    buffer: str = "final"
    buffer_scale: str = "auto"

    @classmethod
    def from_scene(cls, scene, irradiance_size: int = 512) -> "ViewerParams":
        m = scene.material
        p = cls(technique=scene.technique, mix=m.mix, roughness=m.roughness, rho_s=m.rho_s,
                environment_color=tuple(scene.environment.color), environment_intensity=scene.environment.intensity,
                exposure=scene.output.exposure, tonemap=scene.output.tonemap, irradiance_size=int(irradiance_size))
        if scene.lights:
            L = scene.lights[0]
            p.light_color, p.light_intensity = tuple(L.color), float(L.intensity)
        return p

    def copy(self) -> "ViewerParams":
        return dataclasses.replace(self)

    def update(self, values: dict, source: str = "script") -> "ViewerParams":
        """Set fields from a dict, checking names, types and ranges; returns self."""
        names = {f.name: f for f in dataclasses.fields(self)}
        for key, value in values.items():
            if key not in names:
                raise DermisError(f"{source}: unknown parameter '{key}' (known: {', '.join(names)})")
            setattr(self, key, _coerce(key, value, getattr(self, key), source))
        self.validate(source)
        return self

    def validate(self, source: str = "viewer"):
        from dermis.techniques import technique_names

        def need(cond, msg):
            if not cond:
                raise DermisError(f"{source}: {msg}")

        names = technique_names()
        need(self.technique in names, f"unknown technique '{self.technique}' (available: {', '.join(names)})")
        need(self.profile in PROFILES, f"profile must be one of {', '.join(PROFILES)}, got '{self.profile}'")
        for k in ("melanin", "melanin_blend", "hemoglobin", "oxygenation", "mix"):
            need(0.0 <= getattr(self, k) <= 1.0, f"{k} must lie in [0, 1], got {getattr(self, k)}")
        need(0.0 < self.epidermis_mm <= 10.0, f"epidermis_mm must lie in (0, 10] mm, got {self.epidermis_mm}")
        need(self.skin_color in SKIN_COLORS, f"skin_color must be one of {', '.join(SKIN_COLORS)}")
        need(0.01 <= self.roughness <= 1.0, f"roughness must lie in [0.01, 1], got {self.roughness}")
        need(0.0 <= self.rho_s <= 1.0, f"rho_s must lie in [0, 1], got {self.rho_s}")
        need(self.light_intensity >= 0.0, f"light_intensity must be >= 0, got {self.light_intensity}")
        need(self.environment in ENVIRONMENTS, f"environment must be one of {', '.join(ENVIRONMENTS)}")
        need(self.environment_intensity >= 0.0, "environment_intensity must be >= 0")
        need(-20.0 <= self.exposure <= 20.0, f"exposure must lie in [-20, 20] stops, got {self.exposure}")
        need(self.tonemap in TONEMAPS, f"tonemap must be one of {', '.join(TONEMAPS)}")
        need(64 <= self.irradiance_size <= 8192, f"irradiance_size must lie in [64, 8192], got {self.irradiance_size}")
        need(self.buffer_scale in BUFFER_SCALES, f"buffer_scale must be one of {', '.join(BUFFER_SCALES)}")
        for k in ("light_color", "environment_color"):
            v = getattr(self, k)
            need(len(v) == 3 and all(np.isfinite(v)) and min(v) >= 0.0, f"{k} must be three numbers >= 0")

    def profile_request(self) -> tuple:
        """What the skin profile depends on (a hashable key)."""
        if self.profile in ("scene", "deon"):
            return (self.profile,)
        return (self.profile, round(self.melanin, 6), round(self.melanin_blend, 6), round(self.hemoglobin, 6),
                round(self.oxygenation, 6), round(self.epidermis_mm, 6))

    def apply_preset(self, name: str):
        """Choose a profile; a spectral preset also moves the sliders to its parameters."""
        from dermis.profiles.presets import SKIN_PRESETS

        self.profile = name
        if name in SKIN_PRESETS:
            s = SKIN_PRESETS[name]
            self.melanin, self.melanin_blend, self.hemoglobin = s.melanin_fraction, s.melanin_blend, s.hemoglobin_fraction
            self.oxygenation, self.epidermis_mm = s.oxygenation, s.epidermis_thickness_mm


def _coerce(key, value, current, source):
    try:
        if isinstance(current, bool):
            return bool(value)
        if isinstance(current, int):
            if isinstance(value, float) and not value.is_integer():
                raise ValueError
            return int(value)
        if isinstance(current, float):
            return float(value)
        if isinstance(current, tuple):
            v = tuple(float(x) for x in value)
            if len(v) != len(current):
                raise ValueError
            return v
        if isinstance(current, str):
            if not isinstance(value, str):
                raise ValueError
            return value
    except (TypeError, ValueError):
        pass
    else:
        return value
    raise DermisError(f"{source}: parameter '{key}' = {value!r} has the wrong type (like {current!r})")


# ---------------------------------------------------------------------------------- profiles
@dataclass
class ProfileResult:
    request: tuple
    profile: object  # SumOfGaussians
    note: str = ""


def compute_profile(params_request: tuple, scene_profile) -> ProfileResult:
    """The skin profile for a profile request (see ViewerParams.profile_request): the scene's,
    d'Eon's, or a spectral one through ``dermis.profiles.resolve_skin_profile`` (what a scene's
    [skin] section gives: fitted Gaussians whose weights per channel sum to R_d)."""
    from dermis import profiles

    kind = params_request[0]
    if kind == "scene":
        return ProfileResult(params_request, scene_profile)
    if kind == "deon":
        return ProfileResult(params_request, profiles.deon_skin())
    _, mel, blend, hb, oxy, epi = params_request
    section = {"profile": kind, "melanin": mel, "melanin_blend": blend, "hemoglobin": hb, "oxygenation": oxy,
               "epidermis_mm": epi}
    shape = profiles.resolve_skin_profile(section, ".", "viewer")
    return ProfileResult(params_request, shape, "R_d = " + ", ".join(f"{c:.3f}" for c in shape.total_reflectance))


class SkinProfileWorker:
    """Computes profiles on one worker thread, newest request first; results cached by request.

    While a computation runs, further requests replace each other (a dragged slider asks for
    many values): only the last one is computed next.
    """

    CACHE_SIZE = 16

    def __init__(self, scene_profile):
        self.scene_profile = scene_profile
        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="dermis-profile")
        self._cache: dict[tuple, ProfileResult] = {}
        self._running: tuple | None = None  # (key, future)
        self._next: tuple | None = None  # the request to compute when the running one ends

    def _submit(self, key):
        self._running = (key, self._pool.submit(compute_profile, key, self.scene_profile))

    def _collect(self):
        if self._running is not None and self._running[1].done():
            key, fut = self._running
            self._running = None
            try:
                self._cache[key] = fut.result()
            except Exception as exc:  # shown in the panel; the scene keeps its profile
                self._cache[key] = ProfileResult(key, None, f"profile error: {exc}")
            while len(self._cache) > self.CACHE_SIZE:
                self._cache.pop(next(iter(self._cache)))
        if self._running is None and self._next is not None:
            key, self._next = self._next, None
            if key not in self._cache:
                self._submit(key)

    def get(self, params: ViewerParams, wait: bool = False) -> ProfileResult | None:
        """The result for ``params`` if ready (after waiting for it when ``wait``), else None."""
        key = params.profile_request()
        self._collect()
        if key not in self._cache:
            if self._running is None:
                self._submit(key)
            elif self._running[0] != key:
                self._next = key
            while wait and key not in self._cache:
                if self._running is not None:
                    concurrent.futures.wait([self._running[1]])
                self._collect()
                if key not in self._cache and self._running is None:
                    self._submit(key)
        return self._cache.get(key)

    @property
    def busy(self) -> bool:
        return self._running is not None and not self._running[1].done()

    def close(self):
        self._pool.shutdown(wait=False, cancel_futures=True)


# ---------------------------------------------------------------------------------- the scene
@dataclass
class _Originals:
    profile: object
    skin_color: str
    environment: object


class SceneEditor:
    """Writes ViewerParams into a Scene, remembering what the scene had to go back to it."""

    def __init__(self, scene):
        self.scene = scene
        self.orig = _Originals(scene.profile, getattr(scene, "skin_color", "albedo"), copy.copy(scene.environment))
        self._applied_profile_request = ("scene",)

    def apply(self, p: ViewerParams):
        s = self.scene
        m = s.material
        s.technique = p.technique
        m.mix, m.roughness, m.rho_s = float(p.mix), float(p.roughness), float(p.rho_s)
        if s.lights:
            L = s.lights[min(max(p.light_index, 0), len(s.lights) - 1)]
            L.color, L.intensity = tuple(p.light_color), float(p.light_intensity)
        env = s.environment
        if p.environment == "scene":
            env.image, env.color = self.orig.environment.image, tuple(self.orig.environment.color)
            env.intensity = float(p.environment_intensity)
        elif p.environment == "constant":
            env.image, env.color, env.intensity = None, tuple(p.environment_color), float(p.environment_intensity)
        else:
            env.image, env.color, env.intensity = None, (0.0, 0.0, 0.0), 0.0
        s.output.exposure, s.output.tonemap = float(p.exposure), p.tonemap
        # where the skin's colour comes from: only a spectral profile has an R_d to colour it with
        kind = self._applied_profile_request[0]
        if kind == "scene":
            s.skin_color = self.orig.skin_color
        elif kind == "deon":
            s.skin_color = "albedo"
        else:
            s.skin_color = p.skin_color

    def apply_profile(self, result: ProfileResult):
        """Swap in a computed profile (a failed one leaves the scene's)."""
        self.scene.profile = result.profile if result.profile is not None else self.orig.profile
        self._applied_profile_request = result.request

    @property
    def applied_profile_request(self) -> tuple:
        return self._applied_profile_request
