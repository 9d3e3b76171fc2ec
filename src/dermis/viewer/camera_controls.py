"""Orbit, zoom and pan of the camera, and dragging the key light: plain math, no window.

The camera orbits its target on a sphere: ``yaw`` turns about the camera's up axis, ``pitch``
lifts it toward the up axis (clamped short of the poles, where yaw is undefined), ``distance``
is the sphere's radius in scene units. Mouse motion arrives in pixels; the constants below turn
it into angles and distances so that the same drag means the same motion at any window size.
The key light moves on a sphere around the scene's centre the same way (azimuth, elevation).
"""

from __future__ import annotations

import copy
import math

import numpy as np

from dermis.camera import normalize

ORBIT_DEG_PER_PIXEL = 0.4  # one full turn per 900 pixels of drag
LIGHT_DEG_PER_PIXEL = 0.4
ZOOM_FACTOR_PER_STEP = 0.9  # one wheel notch moves the camera 10 % closer
MAX_PITCH_DEG = 89.0  # at +-90 the orbit's yaw axis and view direction coincide


def rotate_about_axis(v, axis, angle_rad: float) -> np.ndarray:
    """Rodrigues' rotation of vector ``v`` by ``angle_rad`` about the unit ``axis`` (right-handed)."""
    v = np.asarray(v, np.float64)
    k = normalize(axis)
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return v * c + np.cross(k, v) * s + k * np.dot(k, v) * (1.0 - c)


def _orbit_basis(up, offset):
    """(right, up, back): an orthonormal frame with ``up`` and the offset's horizontal part."""
    u = normalize(up)
    horizontal = np.asarray(offset, np.float64) - u * np.dot(offset, u)
    if np.linalg.norm(horizontal) < 1e-9:  # looking straight along up: any horizontal will do
        horizontal = np.cross(u, [1.0, 0.0, 0.0])
        if np.linalg.norm(horizontal) < 1e-9:
            horizontal = np.cross(u, [0.0, 0.0, 1.0])
    back = normalize(horizontal)
    right = np.cross(u, back)
    return right, u, back


class OrbitCamera:
    """A camera that orbits ``target``; ``camera()`` gives a dermis Camera for the renderer.

    >>> oc = OrbitCamera.from_camera(scene.camera, scene_radius=1.2)
    >>> oc.orbit(90, 0)           # pixels dragged to the right: the view turns 36 degrees
    >>> r.render("tsd", camera=oc.camera())
    """

    def __init__(self, target, distance: float, yaw_deg: float, pitch_deg: float, *, up=(0.0, 1.0, 0.0),
                 fov_deg: float = 30.0, scene_radius: float = 1.0, basis=None, near=None, far=None):
        self.target = np.asarray(target, np.float64).copy()
        self.distance = float(distance)
        self.yaw_deg = float(yaw_deg)
        self.pitch_deg = float(pitch_deg)
        self.up = normalize(up)
        self.fov_deg = float(fov_deg)
        self.scene_radius = float(scene_radius)
        self.basis = basis if basis is not None else _orbit_basis(self.up, np.array([0.0, 0.0, 1.0]))
        self.near, self.far = near, far
        self._home = (self.target.copy(), self.distance, self.yaw_deg, self.pitch_deg)

    @classmethod
    def from_camera(cls, camera, scene_radius: float = 1.0) -> "OrbitCamera":
        """Start where a scene's Camera is: same eye, target, up and field of view."""
        target = np.asarray(camera.target, np.float64)
        offset = np.asarray(camera.position, np.float64) - target
        distance = max(float(np.linalg.norm(offset)), 1e-6)
        basis = _orbit_basis(camera.up, offset)
        right, up, back = basis
        d = offset / distance
        pitch = math.degrees(math.asin(float(np.clip(np.dot(d, up), -1.0, 1.0))))
        pitch = float(np.clip(pitch, -MAX_PITCH_DEG, MAX_PITCH_DEG))
        yaw = math.degrees(math.atan2(float(np.dot(d, right)), float(np.dot(d, back))))
        return cls(target, distance, yaw, pitch, up=up, fov_deg=camera.fov_deg, scene_radius=scene_radius,
                   basis=basis, near=camera.near, far=camera.far)

    # ------------------------------------------------------------------ state
    @property
    def direction(self) -> np.ndarray:
        """Unit vector from the target to the eye."""
        right, up, back = self.basis
        y, p = math.radians(self.yaw_deg), math.radians(self.pitch_deg)
        return math.cos(p) * (math.sin(y) * right + math.cos(y) * back) + math.sin(p) * up

    @property
    def position(self) -> np.ndarray:
        return self.target + self.distance * self.direction

    def view_axes(self):
        """(right, up) of the image plane in world space."""
        forward = -self.direction
        right = normalize(np.cross(forward, self.up))
        return right, np.cross(right, forward)

    def camera(self):
        """A dermis Camera at the orbit's current eye (new object: the scene's is left alone)."""
        from dermis.scene.model import Camera

        return Camera(position=tuple(float(x) for x in self.position), target=tuple(float(x) for x in self.target),
                      up=tuple(float(x) for x in self.up), fov_deg=self.fov_deg, near=self.near, far=self.far)

    def state(self) -> tuple:
        return (tuple(np.round(self.target, 9)), round(self.distance, 9), round(self.yaw_deg, 9), round(self.pitch_deg, 9))

    # ------------------------------------------------------------------ motion
    def orbit(self, dx_px: float, dy_px: float):
        """Drag right: the scene turns right (the eye moves left); drag down: the eye rises."""
        self.yaw_deg = (self.yaw_deg - dx_px * ORBIT_DEG_PER_PIXEL + 180.0) % 360.0 - 180.0
        self.pitch_deg = float(np.clip(self.pitch_deg + dy_px * ORBIT_DEG_PER_PIXEL, -MAX_PITCH_DEG, MAX_PITCH_DEG))

    def zoom(self, steps: float):
        """Positive steps (wheel forward) move closer; the distance stays within the scene's scale."""
        d = self.distance * ZOOM_FACTOR_PER_STEP ** float(steps)
        lo = max(self.scene_radius * 0.05, 1e-6)
        hi = max(self.scene_radius * 50.0, lo)
        self.distance = float(np.clip(d, lo, hi))

    def pan(self, dx_px: float, dy_px: float, viewport_height_px: int):
        """Move the target in the image plane so that the point under the cursor follows it."""
        units_per_px = 2.0 * self.distance * math.tan(math.radians(self.fov_deg) / 2) / max(int(viewport_height_px), 1)
        right, up = self.view_axes()
        self.target = self.target + (-dx_px * right + dy_px * up) * units_per_px

    def turn_to(self, yaw_deg: float, pitch_deg: float | None = None):
        self.yaw_deg = float(yaw_deg)
        if pitch_deg is not None:
            self.pitch_deg = float(np.clip(pitch_deg, -MAX_PITCH_DEG, MAX_PITCH_DEG))

    def reset(self):
        t, d, y, p = self._home
        self.target, self.distance, self.yaw_deg, self.pitch_deg = t.copy(), d, y, p


class LightOrbit:
    """Moves one light on a sphere about the scene's centre (azimuth about +y, elevation).

    A directional light travels toward the centre; a point or spot light sits on the sphere and
    (for a spot) aims at the centre. ``apply`` writes direction and position into the Light.
    """

    def __init__(self, center, light, scene_radius: float):
        self.center = np.asarray(center, np.float64)
        pos = np.asarray(light.position, np.float64)
        if light.kind == "directional":
            to_light = -normalize(light.direction)
            self.distance = max(float(np.linalg.norm(pos - self.center)), 2.5 * scene_radius)
        else:
            to_light = normalize(pos - self.center)
            self.distance = max(float(np.linalg.norm(pos - self.center)), 1e-3 * scene_radius)
        self.azimuth_deg = math.degrees(math.atan2(to_light[0], to_light[2]))
        self.elevation_deg = math.degrees(math.asin(float(np.clip(to_light[1], -1.0, 1.0))))

    @property
    def to_light(self) -> np.ndarray:
        a, e = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        return np.array([math.sin(a) * math.cos(e), math.sin(e), math.cos(a) * math.cos(e)])

    def drag(self, dx_px: float, dy_px: float):
        """Drag right: the light swings right (seen from the front); drag up: it rises."""
        self.azimuth_deg = (self.azimuth_deg + dx_px * LIGHT_DEG_PER_PIXEL + 180.0) % 360.0 - 180.0
        self.elevation_deg = float(np.clip(self.elevation_deg - dy_px * LIGHT_DEG_PER_PIXEL, -MAX_PITCH_DEG, MAX_PITCH_DEG))

    def apply(self, light):
        t = self.to_light
        light.position = tuple(float(x) for x in self.center + t * self.distance)
        light.direction = tuple(float(x) for x in -t)


def orbit_rig(scene, angle_rad: float, axis=None, center=None):
    """A copy of the scene's lights rotated by ``angle_rad`` about ``axis`` through ``center``
    (default: the camera's up through the camera's target), for turntables whose light orbits."""
    axis = scene.camera.up if axis is None else axis
    c = np.asarray(scene.camera.target if center is None else center, np.float64)
    out = []
    for L in scene.lights:
        M = copy.copy(L)
        M.direction = tuple(float(x) for x in rotate_about_axis(L.direction, axis, angle_rad))
        M.position = tuple(float(x) for x in c + rotate_about_axis(np.asarray(L.position, np.float64) - c, axis, angle_rad))
        out.append(M)
    return out
