"""A render's parameters applied to a loaded Scene (in Python, on the scene model).

Conventions (scene units and degrees; +y is up, as in every dermis scene):
- ``camera.azimuth_deg / elevation_deg / distance``: the camera on a sphere about its target;
  azimuth turns from +z toward +x about +y (the convention of ``frame_camera``), elevation lifts
  toward +y, distance is in scene units. A coordinate that is not given keeps the base camera's.
- ``lights.rotation_deg``: the lights turned about the vertical (+y) axis through the centre of
  the mesh's bounds, same sense as the camera's azimuth; ``lights.intensity`` multiplies each
  light's intensity; ``lights.temperature_k`` sets its colour to a blackbody's (colour_temperature).
  They apply to the lights that [sweep] lights names (default all).
- ``environment.image``: an equirectangular HDR ("none": the scene's constant colour), turned by
  ``environment.rotation_deg`` about +y in the same sense; ``environment.intensity`` scales it.
- ``skin.*``: the keys of a scene file's [skin] table; when any is given they replace the base
  scene's profile, resolved by the scene loader's own code (dermis.scene.toml_scene).
"""

from __future__ import annotations

import copy
import math

import numpy as np

from dermis.camera import FOV_MAX_DEG, FOV_MIN_DEG
from dermis.errors import DermisError

SKIN_PREFIX = "skin."


def spherical_offset(camera) -> tuple[float, float, float]:
    """(azimuth_deg, elevation_deg, distance) of the camera's position about its target."""
    d = np.asarray(camera.position, np.float64) - np.asarray(camera.target, np.float64)
    dist = float(np.linalg.norm(d))
    if dist < 1e-12:
        return 0.0, 0.0, 0.0
    return math.degrees(math.atan2(d[0], d[2])), math.degrees(math.asin(max(-1.0, min(1.0, d[1] / dist)))), dist


def place_camera(camera, azimuth_deg=None, elevation_deg=None, distance=None, fov_deg=None):
    """Move ``camera`` (in place) on its sphere about its target; None keeps a coordinate."""
    az0, el0, d0 = spherical_offset(camera)
    az = math.radians(az0 if azimuth_deg is None else azimuth_deg)
    el = math.radians(el0 if elevation_deg is None else elevation_deg)
    dist = d0 if distance is None else distance
    if not dist > 0:
        raise DermisError(f"camera.distance must be > 0 scene units, got {dist}")
    if not -90.0 <= math.degrees(el) <= 90.0:
        raise DermisError(f"camera.elevation_deg must be in [-90, 90], got {math.degrees(el)}")
    direction = np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
    camera.position = tuple(float(x) for x in np.asarray(camera.target, np.float64) + dist * direction)
    if distance is not None:
        # an explicit distance is the framing asked for: [camera] fit (which moves the camera along
        # its direction to frame the head) would override it; a turned camera alone is still fitted
        camera.fit = False
    if fov_deg is not None:
        if not FOV_MIN_DEG <= fov_deg < FOV_MAX_DEG:
            raise DermisError(f"camera.fov_deg must be in [{FOV_MIN_DEG:g}, {FOV_MAX_DEG:g}) degrees, got {fov_deg}")
        camera.fov_deg = float(fov_deg)


def skin_section(params: dict) -> dict:
    """The [skin] table the render's skin.* parameters make (empty: keep the scene's profile)."""
    return {k[len(SKIN_PREFIX):]: v for k, v in params.items() if k.startswith(SKIN_PREFIX) and v is not None}


class SceneState:
    """A base scene and the parts of it a render changes, to restore before each render.

    The Renderer keeps one Scene object (its GPU copy of the mesh and textures stays uploaded);
    ``apply`` resets lights, camera, environment and profile to the base values and then sets the
    render's parameters on that same object, so the Renderer's caches see exactly what changed."""

    def __init__(self, scene):
        self.scene = scene
        self.lights = [copy.copy(L) for L in scene.lights]
        self.camera = copy.copy(scene.camera)
        self.environment = copy.copy(scene.environment)
        self.profile, self.skin_color, self.technique = scene.profile, scene.skin_color, scene.technique

    def reset(self):
        s = self.scene
        s.lights = [copy.copy(L) for L in self.lights]
        s.camera = copy.copy(self.camera)
        s.environment = copy.copy(self.environment)
        s.profile, s.skin_color, s.technique = self.profile, self.skin_color, self.technique


def apply_parameters(state: SceneState, params: dict, *, light_indices="all", folder=".", source="sweep",
                     environment_image=None) -> dict:
    """Reset the scene to its base and set a render's parameters on it. Returns derived values for the
    metadata (the camera's position, the lights' colours). ``environment_image(source)`` gives the
    equirect Texture of ``source`` (a path from the sweep, or the scene's own Texture); the worker
    caches them so an unchanged environment keeps its identity."""
    from dermis.batch.colour_temperature import blackbody_rgb
    from dermis.scene.toml_scene import resolve_profile_section
    from dermis.viewer.camera_controls import orbit_rig

    state.reset()
    s = state.scene
    p = {k: v for k, v in params.items() if v is not None}
    if "technique" in p:
        s.technique = p["technique"]

    section = skin_section(p)
    if section:
        s.profile, s.skin_color = resolve_profile_section(section, folder, source)

    chosen = list(range(len(s.lights))) if light_indices == "all" else list(light_indices)
    if chosen and max(chosen) >= len(s.lights):
        raise DermisError(f"{source}: [sweep] lights names light {max(chosen)}, the scene has {len(s.lights)}")
    if "lights.rotation_deg" in p:
        lo, hi = s.bounds()
        rotated = orbit_rig(s, math.radians(p["lights.rotation_deg"]), axis=(0.0, 1.0, 0.0),
                            center=(np.asarray(lo, np.float64) + hi) / 2)
        s.lights = [rotated[i] if i in chosen else L for i, L in enumerate(s.lights)]
    if "lights.intensity" in p:
        if p["lights.intensity"] < 0:
            raise DermisError(f"lights.intensity must be >= 0 (a factor on each light's), got {p['lights.intensity']}")
        for i in chosen:
            s.lights[i].intensity = s.lights[i].intensity * p["lights.intensity"]
    if "lights.temperature_k" in p:
        rgb = blackbody_rgb(p["lights.temperature_k"])
        for i in chosen:
            s.lights[i].color = rgb

    env = s.environment
    image = p.get("environment.image")
    base = None if image == "none" else (image if image is not None else env.image)
    if isinstance(base, str) and environment_image is None:
        raise DermisError(f"{source}: environment.image {base!r} needs the worker's image loader")
    env.image = base if base is None or environment_image is None else environment_image(base)
    # turned the way the renderer turns any environment (dermis.environment.rotate_equirect, on top of the
    # scene's own rotation), so the SH projection and the prefiltered map are memoised per angle on the
    # one image, not made for a rotated copy per render; a constant environment is the same any way
    if base is not None and "environment.rotation_deg" in p:
        env.rotation_deg = float(env.rotation_deg) + float(p["environment.rotation_deg"])
    if "environment.intensity" in p:
        if p["environment.intensity"] < 0:
            raise DermisError(f"environment.intensity must be >= 0, got {p['environment.intensity']}")
        env.intensity = float(p["environment.intensity"])

    place_camera(s.camera, p.get("camera.azimuth_deg"), p.get("camera.elevation_deg"), p.get("camera.distance"),
                 p.get("camera.fov_deg"))
    return {"camera_position": [float(x) for x in s.camera.position],
            "light_colors": [[float(c) for c in L.color] for L in s.lights],
            "light_intensities": [float(L.intensity) for L in s.lights]}
