"""Camera and light projection matrices (numpy, column vectors, OpenGL clip conventions)."""

from __future__ import annotations

import math

import numpy as np


def normalize(v):
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v)
    if not math.isfinite(n):
        # components past ~1e154 overflow the sum of squares (a scene may give any finite direction):
        # scale by the largest first, which leaves the direction and every ordinary vector's rounding alone
        v = v / np.abs(v).max()
        n = np.linalg.norm(v)
    return v / max(n, 1e-300)


def cross3(a, b) -> np.ndarray:
    """np.cross of two 3-vectors, term for term as numpy computes it (a1 b2 - a2 b1, ...: the same
    float64 roundings), without its axis bookkeeping (~20 us a call, several per frame)."""
    a0, a1, a2 = (float(x) for x in a)
    b0, b1, b2 = (float(x) for x in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def look_at(eye, target, up) -> np.ndarray:
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    f = normalize(target - eye)
    up = np.asarray(up, np.float64)
    if abs(np.dot(f, normalize(up))) > 0.999:  # looking along up: pick another up
        up = np.array([0.0, 0.0, 1.0]) if abs(f[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    s = normalize(cross3(f, up))
    u = cross3(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fov_y_deg, aspect, near, far) -> np.ndarray:
    if not (0 < fov_y_deg < 180 and aspect > 0 and 0 < near < far):
        raise ValueError(f"perspective: degenerate frustum (fov {fov_y_deg}, aspect {aspect}, near {near}, far {far})")
    f = 1.0 / np.tan(np.radians(fov_y_deg) / 2)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def orthographic(half_w, half_h, near, far) -> np.ndarray:
    m = np.eye(4)
    m[0, 0], m[1, 1] = 1 / half_w, 1 / half_h
    m[2, 2] = -2 / (far - near)
    m[2, 3] = -(far + near) / (far - near)
    return m


def bounding_sphere(lo, hi):
    c = (np.asarray(lo, np.float64) + np.asarray(hi, np.float64)) / 2
    return c, float(np.linalg.norm(np.asarray(hi, np.float64) - lo) / 2)


def camera_matrices(camera, aspect: float, lo, hi):
    """(view, projection, eye, near, far) for a scene Camera; near/far fitted to the bounds."""
    c, r = bounding_sphere(lo, hi)
    eye = np.asarray(camera.position, np.float64)
    d = np.linalg.norm(eye - c)
    near = camera.near if camera.near else max(d - r * 1.5, r * 1e-3, 1e-4)
    far = camera.far if camera.far else d + r * 1.5
    if not far > near:  # one of them given and beyond the other's fitted value: keep a valid range
        if camera.far:
            near = far * 1e-3
        else:
            far = near * 2.0
    return look_at(eye, camera.target, camera.up), perspective(camera.fov_deg, aspect, near, far), eye, near, far


def orthographic_box(x0, x1, y0, y1, near, far) -> np.ndarray:
    """Off-centre orthographic projection of the view-space box [x0, x1] x [y0, y1] x [-far, -near]."""
    if not (x1 > x0 and y1 > y0 and far > near):
        raise ValueError(f"orthographic_box: empty box ({x0}, {x1}, {y0}, {y1}, {near}, {far})")
    m = np.eye(4)
    m[0, 0], m[1, 1] = 2 / (x1 - x0), 2 / (y1 - y0)
    m[0, 3], m[1, 3] = -(x1 + x0) / (x1 - x0), -(y1 + y0) / (y1 - y0)
    m[2, 2] = -2 / (far - near)
    m[2, 3] = -(far + near) / (far - near)
    return m


def light_matrices(light, lo, hi, points=None):
    """View-projection of a light's shadow map covering the scene. Returns (viewproj, eye,
    half_extent): half_extent is half the map's width in scene units (its texel size x tile / 2).

    Directional: orthographic along the light's direction, fitted to the mesh's own silhouette as
    seen from the light when ``points`` (the vertices) are given - for a bust lit from the front that
    is about 1.4x finer per axis than the bounding sphere - else to the bounding sphere. Spot:
    perspective with the cone's angle. Point: perspective aimed at the scene centre (one map, not a
    cube map: a point light inside the scene casts shadows only within that frustum).
    """
    c, r = bounding_sphere(lo, hi)
    r *= 1.02
    d = normalize(light.direction)
    if light.kind == "directional":
        eye = c - d * (2.0 * r)
        view = look_at(eye, c, (0, 1, 0))
        if points is not None and len(points):
            q = np.asarray(points, np.float64) @ view[:3, :3].T + view[:3, 3]
            # per column: numpy's reduction over axis 0 of an (N, 2) view loops per row (10x slower)
            x0, y0, x1, y1 = q[:, 0].min(), q[:, 1].min(), q[:, 0].max(), q[:, 1].max()
            # square texels: the larger extent sets the texel size, plus a 2% margin for PCF
            half = 0.51 * max(x1 - x0, y1 - y0, 1e-9)
            cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
            proj = orthographic_box(cx - half, cx + half, cy - half, cy + half, 0.5 * r, 3.5 * r)
            return proj @ view, eye, half
        proj = orthographic(r, r, 0.5 * r, 3.5 * r)
        return proj @ view, eye, r
    eye = np.asarray(light.position, np.float64)
    dist = np.linalg.norm(c - eye)
    if light.kind == "spot":
        target = eye + d
        fov = min(2 * light.spot_angle_deg + 2.0, 170.0)
    else:
        target = c
        fov = min(2 * np.degrees(np.arcsin(min(r / max(dist, 1e-9), 0.999))) + 2.0, 170.0) if dist > r else 150.0
    near = max(dist - r, dist * 1e-3, 1e-4)
    far = dist + r
    # the map's width at the scene centre's distance (the normal offset's scale)
    half = dist * np.tan(np.radians(fov) / 2)
    return perspective(fov, 1.0, near, far) @ look_at(eye, target, (0, 1, 0)), eye, half


# The field of view a camera may have, degrees, [min, max). Below 0.001 degree the fitted camera
# (dermis.framing) stands more than 1e5 scene radii away and tan(fov / 2) underflows long before
# float64 does (a fov of 1e-193 gave an infinite near plane); above 170 the perspective is degenerate.
FOV_MIN_DEG, FOV_MAX_DEG = 1e-3, 170.0


def check_camera(camera, where: str, center, radius: float):
    """Refuse a camera that cannot give an image (one-line DermisError, ``where`` names it):
    non-finite values, position == target, ``up`` along the view direction, field of view outside
    [FOV_MIN_DEG, FOV_MAX_DEG) degrees, near <= 0, far <= near, a near/far range that does not reach the
    scene, or the whole scene behind the camera."""
    from dermis.errors import DermisError

    vals = {}
    for k in ("position", "target", "up"):
        try:
            a = np.asarray(getattr(camera, k), np.float64).reshape(-1)
        except (TypeError, ValueError):
            a = np.array([np.nan])
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.abs(a).max() > 1e12:
            raise DermisError(f"{where} {k} must be 3 finite numbers, got {getattr(camera, k)!r}")
        vals[k] = a
    view = vals["target"] - vals["position"]
    if np.linalg.norm(view) <= 1e-9 * max(np.abs(vals["position"]).max(), radius, 1e-30):
        raise DermisError(f"{where} position and target coincide: the camera has no view direction")
    up = vals["up"]
    # exactly along the view (within float rounding): no image orientation. Nearly along it is
    # allowed (look_at then picks another up; the viewer orbits to 89 degrees of pitch)
    if np.linalg.norm(up) == 0 or abs(np.dot(normalize(view), normalize(up))) > 1 - 1e-9:
        raise DermisError(f"{where} up must not be zero or parallel to the view direction (target - position)")
    fov = camera.fov_deg
    if isinstance(fov, bool) or not isinstance(fov, (int, float, np.floating)) or not FOV_MIN_DEG <= fov < FOV_MAX_DEG:
        raise DermisError(f"{where} fov_deg must be in [{FOV_MIN_DEG:g}, {FOV_MAX_DEG:g}) degrees, got {fov!r}")
    for k in ("near", "far"):
        v = getattr(camera, k)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not np.isfinite(v)
                              or v <= 0):
            raise DermisError(f"{where} {k} must be a positive finite distance, got {v!r}")
    if camera.near is not None and camera.far is not None and not camera.far > camera.near * (1 + 1e-6):
        raise DermisError(f"{where} far ({camera.far}) must be greater than near ({camera.near})")
    # a clip range that misses the mesh's bounding sphere entirely clips every triangle: an empty
    # image (and a near of 3e38 overflowed the float32 projection, fuzz seed 1616). A range that
    # cuts through the mesh (a cross-section) is the user's choice and stays allowed.
    d = float(np.linalg.norm(np.asarray(center, np.float64) - vals["position"]))
    r = float(radius)
    if camera.near is not None and camera.near >= d + r:
        raise DermisError(f"{where} near ({camera.near:g}) lies beyond the whole scene (its farthest point is "
                          f"{d + r:g} from the camera): nothing would be drawn")
    # the whole bounding sphere behind the camera (whatever the field of view and aspect): an empty image
    if float(np.dot(normalize(view), np.asarray(center, np.float64) - vals["position"])) < -r:
        raise DermisError(f"{where} looks away from the scene: the mesh lies entirely behind the camera "
                          f"(position {tuple(float(x) for x in vals['position'])}, target "
                          f"{tuple(float(x) for x in vals['target'])})")
    if camera.far is not None and camera.far <= d - r:
        raise DermisError(f"{where} far ({camera.far:g}) ends before the scene (its nearest point is "
                          f"{d - r:g} from the camera): nothing would be drawn")
