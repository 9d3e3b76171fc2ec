"""Framing: a perspective camera that fits a mesh in view, keeping its viewing direction.

For a camera looking along f (right r, up u) from e = c + s_x r + s_y u - D f, a vertex p with
x = (p - c).r, y = (p - c).u and z = (p - c).f lies in view when |x - s_x| <= t_x (z + D) and
|y - s_y| <= t_y (z + D), t = tan(half field of view) less the margin. Per axis the smallest
distance is D = (A + B) / 2 with A = max(x / t - z), B = max(-x / t - z), at the lateral shift
s = t (A - B) / 2 (the two constraints balanced); the camera takes the larger of the two axes'
distances. Exact for the vertices (a mesh's silhouette is made of them): nothing is cropped.

A bust (a head on a neck on shoulders, as the Lee Perry-Smith scan) is framed on its head: the
vertices above the neck, the narrowest horizontal section of the mesh's middle (head_vertices).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dermis.camera import cross3, normalize


def head_vertices(positions, up=(0.0, 1.0, 0.0), bins: int = 48, neck_ratio: float = 0.75):
    """The vertices above the neck when ``positions`` is a bust, else all of them. The neck is the
    section (slab of 1/bins of the height along ``up``) of smallest horizontal extent between 25%
    and 75% of the height, if it is under ``neck_ratio`` times the widest section above it."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    up = normalize(np.asarray(up, np.float64))
    h = p @ up
    lo, hi = h.min(), h.max()
    if hi - lo <= 0:
        return p
    side = normalize(np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 0.0, 1.0]))
    depth = np.cross(up, side)
    idx = np.minimum(((h - lo) / (hi - lo) * bins).astype(int), bins - 1)
    width = np.zeros(bins)
    for b in range(bins):
        q = p[idx == b]
        if len(q):
            width[b] = max(np.ptp(q @ side), np.ptp(q @ depth))
    lo_b, hi_b = bins // 4, (3 * bins) // 4
    neck = lo_b + int(np.argmin(width[lo_b:hi_b]))
    if width[neck] >= neck_ratio * width[neck + 1:].max():
        return p
    return p[idx >= neck]


def _box_centre(p: np.ndarray) -> np.ndarray:
    return (p.min(axis=0) + p.max(axis=0)) / 2


def fit_camera(camera, positions, aspect: float, margin: float = 0.04, centre=None):
    """A copy of ``camera`` moved along and across its viewing direction so that every vertex of
    ``positions`` (N, 3, scene units) projects inside the view with ``margin`` (fraction of the
    half-width) to spare; direction, up vector and field of view are kept. ``aspect`` = W / H.
    ``centre``: the centre of the positions' bounding box, if the caller has it."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    eye = np.asarray(camera.position, np.float64)
    f = normalize(np.asarray(camera.target, np.float64) - eye)
    r = normalize(cross3(f, np.asarray(camera.up, np.float64)))
    u = cross3(r, f)
    c = _box_centre(p) if centre is None else centre
    q = p - c
    x, y, z = q @ r, q @ u, q @ f
    t_y = np.tan(np.radians(camera.fov_deg) / 2) * (1.0 - margin)
    t_x = t_y * aspect

    def axis(coord, t):
        a = np.max(coord / t - z)
        b = np.max(-coord / t - z)
        return (a + b) / 2, t * (a - b) / 2

    d_x, s_x = axis(x, t_x)
    d_y, s_y = axis(y, t_y)
    dist = max(d_x, d_y, 1e-6)
    position = c + s_x * r + s_y * u - dist * f
    return dataclasses.replace(camera, position=tuple(position), target=tuple(position + dist * f))


def framed_camera(camera, mesh, aspect: float):
    """The camera a frame is rendered with: ``camera`` itself, or, when ``camera.fit`` is set, a
    copy fitted to the mesh (a bust: to its head). The renderer, the viewer's starting view and
    anything that must match the rendered pixels (a batch's depth map) use this one function."""
    if not getattr(camera, "fit", False):
        return camera
    from dermis.invalidation import memo_by_content, read_only

    up = tuple(float(x) for x in camera.up)

    def head():  # per mesh content and up vector, not per frame (a pass over the mesh: ~4 ms)
        from dermis.geometry.hull import extreme_points

        p = head_vertices(mesh.positions, up)
        # the fit's maxima are linear in the vertices: its hull's hold them (577 of the head's 8324)
        return read_only(extreme_points(p)), read_only(_box_centre(p))
    p, c = memo_by_content("framing.head", (mesh.positions,), up, head)
    try:  # the fit itself per view too: a frame whose camera did not move (lights moving) reuses it
        view = (tuple(float(x) for x in camera.position), tuple(float(x) for x in camera.target), up,
                float(camera.fov_deg), float(aspect))
    except (TypeError, ValueError):
        return fit_camera(camera, p, aspect, centre=c)
    last = memo_by_content("framing.fit", (mesh.positions,), up, dict)  # {view: fit}, the last one per mesh content
    fitted = last.get(view)
    if fitted is None:
        fitted = fit_camera(camera, p, aspect, centre=c)
        last.clear()
        last[view] = fitted
    return dataclasses.replace(camera, position=fitted.position, target=fitted.target)
