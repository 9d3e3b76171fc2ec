"""The points of a cloud that can hold the maximum of a linear function: its convex hull's.

Fitting a view (dermis.framing.fit_camera) or a shadow map (dermis.camera.light_matrices) to a
mesh takes maxima of linear functions of its vertices (x / t - z along the view; extents along a
light's axes). Over a convex hull the maximum of a linear function is reached at a vertex, so the
fits need only the hull's vertices: 577 of the head's 8324 (framing) and a few hundred of its
9279 (shadows), found once per mesh content (scipy.spatial.ConvexHull, Qhull). Qhull merges
facets within its rounding tolerance; the points it finds coplanar with a facet (option Qc) are
kept too, so a point whose value ties the maximum in floating point is never dropped.
"""

from __future__ import annotations

import numpy as np


def extreme_points(points) -> np.ndarray:
    """The rows of ``points`` (N, 3) that are vertices of its convex hull or coplanar with a hull
    facet, in their original order, as a new contiguous float64 array; all rows when the cloud
    has no 3-D hull (fewer than 5 points, flat, or Qhull fails)."""
    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    if len(p) < 5:
        return p.copy()
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(p, qhull_options="Qc")  # Qc: also report the points coplanar with a facet
    except (QhullError, ValueError):
        return p.copy()
    keep = np.zeros(len(p), bool)
    keep[hull.vertices] = True
    if len(hull.coplanar):
        keep[hull.coplanar[:, 0]] = True
    return np.ascontiguousarray(p[keep])
