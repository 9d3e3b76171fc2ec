"""The viewer's live parameters and how they reach the Scene.

:class:`ViewerParams` is everything the panel (or a script) can change. :class:`SceneEditor`
writes it into the Scene that the Renderer draws; the Renderer notices through its lighting key
(material, lights, environment, profile), so only what changed re-runs. Skin profiles from
physics take about a second to compute, so :class:`SkinProfileWorker` computes them off the
render thread and the viewer swaps the result in when it is ready.

Skin colour from the physical model: a diffusion profile's total reflectance R_d (its integral
over the plane, per channel) is the skin's diffuse colour. The techniques take their colour from
the albedo map and use each profile's weights normalised to sum to 1, so in ``skin_colour =
"model"`` mode the viewer recolours the albedo map: the map keeps its variation (lips, freckles,
stubble) and its mean colour becomes the spectral model's R_d (Donner & Jensen 2006 parameters:
melanin, melanin blend, haemoglobin, oxygenation, epidermis thickness). Without a map the
material's flat colour becomes R_d.
"""

from __future__ import annotations

import concurrent.futures
import copy
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from dermis.errors import DermisError

PROFILES = ("scene", "deon", "fair", "asian", "dark", "physical")
SKIN_COLOURS = ("map", "model")
ENVIRONMENTS = ("scene", "constant", "off")
TONEMAPS = ("aces", "linear")
IRRADIANCE_SIZES = (128, 256, 512, 1024, 2048)
BUFFER_SCALES = ("auto", "exposure")
#: luminance below which an albedo texel counts as background when its mean colour is measured
ALBEDO_BACKGROUND_LUMINANCE = 0.02


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
    skin_colour: str = "model"  # for physical profiles: "model" recolours the albedo to R_d, "map" keeps it
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
        need(self.skin_colour in SKIN_COLOURS, f"skin_colour must be one of {', '.join(SKIN_COLOURS)}")
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

    def skin_parameters(self):
        """The Donner & Jensen 2006 parameters of the sliders (dermis.profiles.spectral)."""
        from dermis.profiles.spectral import SkinParameters

        return SkinParameters(melanin_fraction=self.melanin, melanin_blend=self.melanin_blend,
                              hemoglobin_fraction=self.hemoglobin, oxygenation=self.oxygenation,
                              epidermis_thickness_mm=self.epidermis_mm)

    def profile_request(self) -> tuple:
        """What the skin profile depends on (a hashable key)."""
        if self.profile in ("scene", "deon"):
            return (self.profile,)
        return (self.profile, round(self.melanin, 6), round(self.melanin_blend, 6), round(self.hemoglobin, 6),
                round(self.oxygenation, 6), round(self.epidermis_mm, 6), self.skin_colour)

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
    profile: object  # SumOfGaussians, or None: keep the scene's
    skin_rgb: np.ndarray | None  # R_d to recolour the albedo to, or None: keep the map
    note: str = ""


def retint_albedo(albedo: np.ndarray, target_rgb) -> np.ndarray:
    """The map with its mean colour (over texels brighter than the background) moved to
    ``target_rgb``, its variation kept: albedo * target / mean, clipped to [0, 1]."""
    a = np.asarray(albedo, np.float32)[:, :, :3]
    lum = a @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    skin = a[lum > ALBEDO_BACKGROUND_LUMINANCE]
    mean = skin.mean(axis=0) if len(skin) else a.reshape(-1, 3).mean(axis=0)
    scale = np.asarray(target_rgb, np.float32) / np.maximum(mean, 1e-6)
    return np.clip(a * scale, 0.0, 1.0).astype(np.float32)


def compute_profile(params_request: tuple, scene_profile, skin_parameters=None) -> ProfileResult:
    """The skin profile and colour for a profile request (see ViewerParams.profile_request).

    Spectral profiles come from ``dermis.profiles.resolve_skin_profile`` (what a scene's [skin]
    section gives: the fitted Gaussians, whose weights per channel sum to the total diffuse
    reflectance R_d); their R_d is the skin colour of ``skin_colour = "model"``.
    """
    from dermis import profiles
    from dermis.profiles.gaussians import deon_skin

    kind = params_request[0]
    if kind == "scene":
        return ProfileResult(params_request, scene_profile, None)
    if kind == "deon":
        return ProfileResult(params_request, deon_skin(), None)
    _, mel, blend, hb, oxy, epi, colour = params_request
    try:
        resolver = profiles.resolve_skin_profile
    except AttributeError:
        resolver = None
    if resolver is None:  # an older build: colour from the spectral model, shape from the scene
        r_d = np.asarray(profiles.skin_profile(skin_parameters, "pbd").total_reflectance_rgb, np.float32)
        return ProfileResult(params_request, scene_profile, r_d if colour == "model" else None,
                             "profile shape: the scene's (no dermis.profiles.resolve_skin_profile in this build)")
    section = {"profile": kind, "melanin": mel, "melanin_blend": blend, "hemoglobin": hb, "oxygenation": oxy,
               "epidermis_mm": epi}
    shape = resolver(section, ".", "viewer")
    r_d = np.asarray(shape.total_reflectance, np.float32)
    note = "R_d = " + ", ".join(f"{c:.3f}" for c in r_d)
    return ProfileResult(params_request, shape, r_d if colour == "model" else None, note)


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
        self._next: tuple | None = None  # (key, SkinParameters or None)

    def _submit(self, key, skin):
        self._running = (key, self._pool.submit(compute_profile, key, self.scene_profile, skin))

    def _collect(self):
        if self._running is not None and self._running[1].done():
            key, fut = self._running
            self._running = None
            try:
                self._cache[key] = fut.result()
            except DermisError as exc:
                self._cache[key] = ProfileResult(key, None, None, f"profile error: {exc}")
            while len(self._cache) > self.CACHE_SIZE:
                self._cache.pop(next(iter(self._cache)))
        if self._running is None and self._next is not None:
            key, skin = self._next
            self._next = None
            if key not in self._cache:
                self._submit(key, skin)

    def get(self, params: ViewerParams, wait: bool = False) -> ProfileResult | None:
        """The result for ``params`` if ready (after waiting for it when ``wait``), else None."""
        key = params.profile_request()
        self._collect()
        if key not in self._cache:
            skin = params.skin_parameters() if key[0] not in ("scene", "deon") else None
            if self._running is None:
                self._submit(key, skin)
            elif self._running[0] != key:
                self._next = (key, skin)
            while wait and key not in self._cache:
                if self._running is not None:
                    concurrent.futures.wait([self._running[1]])
                self._collect()
                if key not in self._cache and self._running is None:
                    self._submit(key, skin)
        return self._cache.get(key)

    @property
    def busy(self) -> bool:
        return self._running is not None and not self._running[1].done()

    def close(self):
        self._pool.shutdown(wait=False, cancel_futures=True)


# ---------------------------------------------------------------------------------- the scene
@dataclass
class _Originals:
    albedo: object
    albedo_color: tuple
    profile: object
    environment: object
    light_colors: list = field(default_factory=list)


class SceneEditor:
    """Writes ViewerParams into a Scene, remembering what the scene had to go back to it."""

    def __init__(self, scene):
        self.scene = scene
        m = scene.material
        self.orig = _Originals(m.albedo, tuple(m.albedo_color), scene.profile, copy.copy(scene.environment))
        self._applied_profile_request = ("scene",)
        self._retinted: dict = {}

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

    def apply_profile(self, result: ProfileResult):
        """Swap in a computed profile and the albedo it asks for."""
        s, m = self.scene, self.scene.material
        s.profile = result.profile if result.profile is not None else self.orig.profile
        if result.skin_rgb is None:
            m.albedo, m.albedo_color = self.orig.albedo, self.orig.albedo_color
        elif self.orig.albedo is not None:
            key = tuple(np.round(result.skin_rgb, 6))
            tex = self._retinted.get(key)
            if tex is None:
                from dermis.scene.model import Texture

                tex = Texture(retint_albedo(self.orig.albedo.data, result.skin_rgb), self.orig.albedo.source + " (recoloured)")
                self._retinted = {key: tex}  # keep one: each is a full-size image
            m.albedo = tex
        else:
            m.albedo, m.albedo_color = None, tuple(float(x) for x in result.skin_rgb)
        self._applied_profile_request = result.request

    @property
    def applied_profile_request(self) -> tuple:
        return self._applied_profile_request
