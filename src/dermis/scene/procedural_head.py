"""The built-in default scene's geometry and textures: a procedural head-and-neck bust.

Everything here is generated from code (numpy/scipy only, no files, no GL), deterministically for
a given seed, so that ``dermis render`` with no arguments gives a meaningful skin image anywhere.

Geometry (scene units are centimetres, ``mm_per_unit = 10``; y up, the face looks toward +z, the
subject's left is +x):

* The head and neck are one smooth implicit surface: smooth unions of ellipsoids / capsules
  (cranium, forehead, cheeks, jaw, chin, lips, nose, brow ridge, sterno-cleido-mastoid muscles,
  neck) minus smooth subtractions (eye sockets, nostrils, mouth corners), with closed eyelids
  (eyeball spheres) and a flat cut at the bottom of the neck.  It is star-shaped around a centre
  ``C`` inside the head, so it is meshed by casting rays from ``C``.
* Meshing avoids poles and grazing rays: a *ring* grid (columns at fixed azimuth, denser on the
  face; rows re-sampled per column at equal weighted arc length, denser on the face) from the
  hairline down to the neck cut, a *top cap* and a flat *bottom cap* triangulated (Delaunay) in a
  normalised disc whose boundary is exactly the ring's first / last row.
* The ears are separate, genuinely thin closed shells (about 2.6 mm thick flap, up to ~4 mm at
  the helix rim and lobe, rounded edges) whose front edge is buried in the side of the head (they
  interpenetrate it, like a sculpt base mesh), so they transmit light when back-lit.
* Concave parts: eye sockets (closed lids sit about 1 cm behind brow and cheek), nostrils
  (tunnels toward ``C``, about 5 mm deep), mouth corners.

UV layout (unique, for texture-space diffusion): seven islands -- the ring (cut once, down the
back of the head and neck), the top cap, the bottom cap, and the front / back sheet of each ear
(seam along the ear rim) -- each flattened with least-squares conformal maps (LSCM; conformal, so
dP/du and dP/dv are orthogonal and equally long and the MikkTSpace-like tangent frame is
consistent with the normal map), scaled to one common texel density (the bottom cut face, which
is never seen, gets half), oriented so that every UV triangle is counter-clockwise (tangent
handedness w = +1 everywhere) and packed into [0, 1]^2 with gutters of at least
``GUTTER_UV`` (>= 10 texels at 1024^2).  The gutters of every texture are filled with the colour
of the nearest island texel (dilation), so bilinear filtering and blurs never pick up black.

Textures (row 0 = top of the image, i.e. texel (row, col) is at u = (col + .5) / W,
v = 1 - (row + .5) / H; v = 0 is the bottom row, the OpenGL convention used by the UVs):

* ``albedo``: linear RGB, fair skin (mean ~ (0.45, 0.25, 0.17)) with low-frequency melanin and
  redness blotches (3-D noise, so they are continuous across UV seams), redness on cheeks, nose
  and ears, freckles (1-2 mm spots, mostly on nose and cheeks), eyebrows, closed eyelids with a
  dark lash line, darker nostrils, red lips (~(0.45, 0.12, 0.10)).
* ``normal_map``: tangent-space (OpenGL: +x along +u, +y along +v, encoded n * 0.5 + 0.5) from a
  height field in millimetres: pores (dimples on a jittered grid ``pore_spacing_mm`` = 1.0 mm apart,
  ~100 per cm^2 -- the density of visible facial pores; at 1024^2 the layout has ~0.5 mm texels, so
  finer spacings could not be represented), fine micro-relief noise, forehead lines, crow's feet,
  lip lines, the eyelid closure groove and a soft naso-labial fold.
* ``specular``: intensity in [0, 1]: oily T-zone (forehead, nose, chin) and lips brighter,
  eyebrows and pores duller.

``build_default_head`` is cached (``functools.lru_cache``); the arrays it returns are read-only,
copy them before modifying.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, sparse, spatial
from scipy.sparse.linalg import splu

MM_PER_UNIT = 10.0
PORE_SPACING_MM = 1.0
GUTTER_UV = 12.0 / 1024.0  # minimum distance between UV islands (packing target)
MARGIN_UV = 6.0 / 1024.0  # minimum distance of an island from the border of [0, 1]^2


@dataclass
class ProceduralHead:
    positions: np.ndarray  # (N, 3) float32, centimetres, y up, face toward +z
    normals: np.ndarray  # (N, 3) float32, unit, outward, smooth
    uvs: np.ndarray  # (N, 2) float32, v = 0 is the bottom row of the textures
    indices: np.ndarray  # (M, 3) uint32, counter-clockwise seen from outside
    albedo: np.ndarray  # (H, W, 3) float32 linear RGB in [0, 1], row 0 = top
    normal_map: np.ndarray  # (H, W, 3) float32 tangent space, n * 0.5 + 0.5, OpenGL (+y = +v)
    specular: np.ndarray  # (H, W) float32 in [0, 1]
    mm_per_unit: float = MM_PER_UNIT
    pore_spacing_mm: float = PORE_SPACING_MM
    landmarks: dict = field(default_factory=dict)  # name -> (3,) float32 point, scene units
    islands: np.ndarray | None = None  # (M,) int8 UV island of each triangle (see ISLANDS)
    texel_mm: float = 0.0  # mean millimetres per texel of the skin islands at this texture size


ISLANDS = ("ring", "top_cap", "bottom_cap", "left_ear_front", "left_ear_back", "right_ear_front", "right_ear_back")


# ----------------------------------------------------------------------------------------------
# implicit surface
# ----------------------------------------------------------------------------------------------


def _smin(a, b, k):
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.minimum(a, b) - h * h * (k * 0.25)


def _smax(a, b, k):
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.maximum(a, b) + h * h * (k * 0.25)


def _rot(yaw=0.0, pitch=0.0, roll=0.0):
    """Rotation matrix (world -> local rows): local axes as rows."""
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
    return (ry @ rx @ rz).T


class _Ellipsoid:
    def __init__(self, c, r, R=None):
        self.c = np.asarray(c, float)
        self.r = np.asarray(r, float)
        self.R = None if R is None else np.asarray(R, float)
        self.bound = float(np.max(self.r))

    def __call__(self, p):
        q = p - self.c
        if self.R is not None:
            q = q @ self.R.T
        q0 = q / self.r
        q1 = q0 / self.r
        k0 = np.sqrt(np.einsum("ij,ij->i", q0, q0))
        k1 = np.sqrt(np.einsum("ij,ij->i", q1, q1))
        return k0 * (k0 - 1.0) / np.maximum(k1, 1e-12)


class _Capsule:
    """Segment a-b with a radius varying linearly from ra to rb (a round cone, approximately)."""

    def __init__(self, a, b, ra, rb=None, scale=(1.0, 1.0, 1.0)):
        self.a = np.asarray(a, float)
        self.b = np.asarray(b, float)
        self.ra = float(ra)
        self.rb = float(ra if rb is None else rb)
        self.s = np.asarray(scale, float)
        self.c = 0.5 * (self.a + self.b)
        self.bound = 0.5 * float(np.linalg.norm(self.b - self.a)) + max(self.ra, self.rb) * float(self.s.max())

    def __call__(self, p):
        ba = self.b - self.a
        pa = p - self.a
        h = np.clip(pa @ ba / (ba @ ba), 0.0, 1.0)
        d = (pa - h[:, None] * ba) / self.s
        return np.sqrt(np.einsum("ij,ij->i", d, d)) * self.s.min() - (self.ra + (self.rb - self.ra) * h)


class _Shape:
    """The head-and-neck implicit surface (negative inside), in centimetres."""

    # ray centre, neck cut
    C = np.array([0.0, 0.8, -0.3])
    Y_CUT = -19.0
    # features shared by the geometry and the texture masks
    EYE = np.array([3.2, 1.55, 6.95])  # eyeball centre (x mirrored)
    EYE_R = 1.25
    STOMION_Y = -4.9
    NOSTRIL = np.array([0.62, -2.72, 9.85])

    def __init__(self):
        E, Cap = _Ellipsoid, _Capsule
        self.ops = []  # (op, primitive, k)

        def add(prim, k):
            self.ops.append(("u", prim, k))
            self.__dict__.pop("_groups", None)

        def sub(prim, k):
            self.ops.append(("s", prim, k))
            self.__dict__.pop("_groups", None)

        # --- masses (centimetres; tragion ~ (±7, 0, 0), eyes at y ~ 1.6, chin at y ~ -10)
        self.base = E((0, 3.5, -0.6), (7.2, 8.9, 9.4))  # cranium
        add(E((0, 5.0, 3.4), (6.3, 6.0, 5.9)), 2.0)  # forehead
        add(E((0, 6.0, -2.4), (7.3, 6.2, 7.4)), 2.0)  # parietal eminences
        add(E((0, -0.6, 3.0), (6.75, 5.2, 6.3)), 2.4)  # mid-face (zygomatic width)
        add(E((0, -5.2, 2.9), (5.0, 3.6, 5.6), _rot(pitch=0.3)), 2.2)  # jaw mass
        # neck (slightly elliptic, widening a little toward the base) and the
        # sterno-cleido-mastoid muscles
        add(Cap((0, -4.0, -1.7), (0, -30.0, -0.6), 5.35, 6.5, scale=(1.0, 1.0, 1.07)), 3.0)
        for s in (1, -1):
            add(Cap((s * 4.7, -3.0, -2.6), (s * 1.9, -24.0, 2.0), 1.2, 1.5), 1.8)
        for s in (1, -1):
            # jaw line (gonion -> chin)
            add(Cap((s * 4.8, -6.9, -0.4), (s * 1.4, -9.1, 6.6), 0.9, 0.9), 1.6)
            # cheekbones and cheeks
            add(E((s * 4.8, 0.4, 5.2), (1.8, 1.2, 2.0)), 1.6)
            add(E((s * 3.6, -2.3, 5.9), (2.6, 2.6, 2.6)), 2.4)
            # brow ridge
            add(E((s * 2.5, 3.15, 7.9), (2.4, 0.9, 1.4), _rot(yaw=s * 0.35)), 1.2)
        # chin
        add(E((0, -8.4, 7.7), (1.95, 1.75, 1.8)), 1.4)
        # mouth: muzzle and lips
        add(E((0, -4.6, 6.75), (3.1, 2.6, 2.3)), 1.6)
        add(E((0, -4.3, 8.62), (2.15, 0.56, 1.05), _rot(pitch=-0.25)), 0.55)
        add(E((0, -5.5, 8.48), (1.95, 0.6, 0.92), _rot(pitch=0.2)), 0.45)
        # nose: bridge, tip, wings, base
        add(Cap((0, 2.3, 8.45), (0, -1.45, 10.3), 0.45, 0.68), 0.7)
        add(E((0, -1.8, 10.45), (0.75, 0.7, 0.78)), 0.5)
        for s in (1, -1):
            add(E((s * 1.1, -2.15, 9.25), (0.62, 0.58, 0.8), _rot(yaw=s * 0.5)), 0.6)
        add(E((0, -0.9, 8.45), (1.35, 2.1, 1.35)), 0.8)
        # eye sockets, then the closed eyes (eyeball spheres)
        for s in (1, -1):
            sub(E((s * 3.0, 2.15, 9.05), (1.7, 1.0, 1.1), _rot(yaw=s * 0.3)), 1.0)
        for s in (1, -1):
            add(E((s * self.EYE[0], self.EYE[1], self.EYE[2]), (self.EYE_R,) * 3), 0.8)
        # Cavities are carved with ellipsoids elongated toward the ray centre C and centred on
        # the surface (so their walls widen toward the opening and the surface stays
        # star-shaped around C): nostrils, mouth line (a thin slit) and mouth corners.
        def cavity(target, radii, k):
            target = np.asarray(target, float)
            ax = self.C - target
            ax /= np.linalg.norm(ax)
            t = _raycast(self, self.C, -ax[None], iters=12, tol=1e-4)[0]
            sub(E(self.C - t * ax, radii, _frame_from_axis(ax)), k)

        # nostrils, mouth line, mouth corners
        for s in (1, -1):
            cavity((s * self.NOSTRIL[0], self.NOSTRIL[1], self.NOSTRIL[2]), (0.27, 0.17, 0.7), 0.12)

    def sdf(self, p):
        return np.maximum(self.sdf_body(p), self.Y_CUT - p[:, 1])

    def sdf_body(self, p):
        """The surface without the flat cut at the bottom of the neck."""
        d = self.base(p)
        if not hasattr(self, "_groups"):
            self._make_groups()
        for gc, gr, gk, ops in self._groups:
            q = p - gc
            m = np.einsum("ij,ij->i", q, q) < (gr + gk + np.abs(d)) ** 2
            if gr > 1e3:
                m[:] = True
            if not np.any(m):
                continue
            idx = np.nonzero(m)[0]
            pi, di = p[idx], d[idx]
            for op, prim, k in ops:
                q = pi - prim.c
                lim = 1.3 * prim.bound + k + np.abs(di)
                mm = np.einsum("ij,ij->i", q, q) < lim * lim
                if not np.any(mm):
                    continue
                j = np.nonzero(mm)[0]
                e = prim(pi[j])
                di[j] = _smin(di[j], e, k) if op == "u" else _smax(di[j], -e, k)
            d[idx] = di
        return d

    def _make_groups(self):
        """Two-level culling: the face features form one group with a bounding sphere."""
        face_c = np.array([0.0, -1.5, 8.0])
        glob, face = [], []
        for op in self.ops:
            prim = op[1]
            if np.linalg.norm(prim.c - face_c) + 1.3 * prim.bound < 8.5:
                face.append(op)
            else:
                glob.append(op)
        kmax = max(op[2] for op in face)
        self._groups = [(np.zeros(3), 1e9, 0.0, glob), (face_c, 8.5, kmax, face)]


def _frame_from_axis(ax):
    """Rows: x' (as close to world x as possible), y', then ``ax`` (a world -> local rotation
    with local z = ax)."""
    ax = np.asarray(ax, float)
    h = np.array([1.0, 0, 0]) if abs(ax[0]) < 0.9 else np.array([0, 1.0, 0])
    a = h - (h @ ax) * ax
    a /= np.linalg.norm(a)
    b = np.cross(ax, a)
    return np.stack([a, b, ax])


def _raycast(shape, origin, dirs, t_lo=0.2, t_hi=32.0, iters=14, tol=2e-4):
    """First crossing of the surface along origin + t * dirs (surface assumed star-shaped).

    Illinois false position on the bracket [t_lo, t_hi], with a bisection step every third
    iteration; rays stop once the bracket is narrower than ``tol`` or after ``iters`` false-
    position steps (+ up to 3x as many for slowly converging, e.g. grazing, rays)."""
    dirs = np.asarray(dirs, float)
    origin = np.broadcast_to(np.asarray(origin, float), dirs.shape)
    n = len(dirs)
    a = np.full(n, t_lo, float) if np.isscalar(t_lo) else np.asarray(t_lo, float).copy()
    b = np.full(n, t_hi, float) if np.isscalar(t_hi) else np.asarray(t_hi, float).copy()
    fa = shape.sdf(origin + a[:, None] * dirs)
    fb = shape.sdf(origin + b[:, None] * dirs)
    side = np.zeros(n, np.int8)
    act = np.arange(n)
    for it in range(4 * iters):
        if it >= iters:
            act = act[(b[act] - a[act]) > tol]
            if len(act) == 0:
                break
        A, B, FA, FB = a[act], b[act], fa[act], fb[act]
        if it % 3 == 2:
            t = 0.5 * (A + B)
        else:
            t = (A * FB - B * FA) / (FB - FA)
            w = B - A
            t = np.clip(t, A + 0.01 * w, B - 0.01 * w)
        ft = shape.sdf(origin[act] + t[:, None] * dirs[act])
        neg = ft < 0
        sd = side[act]
        a[act] = np.where(neg, t, A)
        fa[act] = np.where(neg, ft, np.where(sd == -1, FA * 0.5, FA))
        b[act] = np.where(neg, B, t)
        fb[act] = np.where(neg, np.where(sd == 1, FB * 0.5, FB), ft)
        side[act] = np.where(neg, 1, -1)
    t = (a * fb - b * fa) / (fb - fa)
    return np.clip(t, a, b)


def _raycast_bracketed(shape, origin, dirs, t_guess, half=0.4, iters=6):
    """Ray cast with a bracket around a guess; rays whose bracket has no sign change fall back
    to the full bracket."""
    origin = np.broadcast_to(np.asarray(origin, float), dirs.shape)
    lo, hi = np.maximum(t_guess - half, 0.2), t_guess + half
    flo = shape.sdf(origin + lo[:, None] * dirs)
    fhi = shape.sdf(origin + hi[:, None] * dirs)
    ok = (flo < 0) & (fhi > 0)
    t = np.empty(len(dirs))
    if np.any(ok):
        t[ok] = _raycast(shape, origin[ok], dirs[ok], lo[ok], hi[ok], iters)
    if not np.all(ok):
        bad = ~ok
        t[bad] = _raycast(shape, origin[bad], dirs[bad], iters=14)
    return t


# ----------------------------------------------------------------------------------------------
# meshing
# ----------------------------------------------------------------------------------------------

N_COLS = 176  # ring columns (azimuth), denser on the face
N_ROWS = 112  # ring rows (hairline -> neck cut), denser on the face
CAP_POLAR = np.radians(40.0)  # the top cap covers directions within this angle of +y (from C)


def _azimuth_warp(s):
    """s in [0, 1] -> azimuth in [-pi, pi] (0 = front, +x side positive), denser on the face."""
    phi = np.linspace(-np.pi, np.pi, 4097)
    dens = 1.0 + 1.15 * np.exp(-((phi / 0.95) ** 2))
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(phi))])
    cum /= cum[-1]
    return np.interp(s, cum, phi)


def _dirs(phi, elev):
    ce = np.cos(elev)
    return np.stack([ce * np.sin(phi), np.sin(elev), ce * np.cos(phi)], -1)


def _face_weight(p):
    """Row density weight: about 2.2x on the face."""
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    front = np.clip((z - 3.0) / 3.0, 0.0, 1.0)
    front = front * front * (3 - 2 * front)
    return 1.0 + 1.2 * np.exp(-((x / 4.8) ** 2) - ((y + 2.0) / 6.5) ** 2) * front


def _grid_tris(rows, cols, base=0):
    """Triangles of a (rows+1) x (cols+1) vertex grid, indexed [i, j] -> base + i*(cols+1) + j."""
    idx = base + np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    return a, b, c, d


def _split_quads(P, a, b, c, d):
    """Split quads a-b-c-d along the shorter diagonal; returns (n, 3) triangles (a, d, c) order
    convention: a -> d -> c -> b is the intended counter-clockwise order of the quad."""
    a, b, c, d = (x.ravel() for x in (a, b, c, d))
    ac = np.linalg.norm(P[a] - P[c], axis=1)
    bd = np.linalg.norm(P[b] - P[d], axis=1)
    use_ac = ac <= bd
    t1 = np.where(use_ac[:, None], np.stack([a, d, c], 1), np.stack([a, d, b], 1))
    t2 = np.where(use_ac[:, None], np.stack([a, c, b], 1), np.stack([d, c, b], 1))
    return np.concatenate([t1, t2])


def _orient_outward(P, tris, ref):
    """Flip the winding of all triangles if most face normals point toward ``ref`` (a point or
    a direction function)."""
    n = np.cross(P[tris[:, 1]] - P[tris[:, 0]], P[tris[:, 2]] - P[tris[:, 0]])
    cen = P[tris].mean(1)
    out = cen - ref if not callable(ref) else ref(cen)
    if np.sum(np.einsum("ij,ij->i", n, out)) < 0:
        tris = tris[:, ::-1].copy()
    return tris


def _disc_points(n_boundary_phis, K, scale_fn=None, warp=True):
    """Concentric rings in the unit disc (boundary excluded) for a cap triangulation."""
    pts = [np.zeros((1, 2))]
    nb = len(n_boundary_phis)
    for k in range(1, K):
        r = k / K
        m = max(6, int(round(nb * (scale_fn(r) if scale_fn else r))))
        s = (np.arange(m) + 0.5 * (k % 2)) / m
        ph = _azimuth_warp(s) if warp else s * 2 * np.pi - np.pi
        pts.append(np.stack([r * np.sin(ph), r * np.cos(ph)], 1))
    return np.concatenate(pts)


def _build_head_surface(shape):
    """Ring + top cap + bottom cap of the head-and-neck surface.

    Returns dict of parts: name -> (positions, triangles) (triangles index the part's own
    vertices, counter-clockwise from outside); the ring has a duplicated seam column."""
    C = shape.C
    Nc, Nr = N_COLS, N_ROWS
    phis = _azimuth_warp(np.arange(Nc + 1) / Nc)  # column Nc repeats column 0 (seam at the back)
    e0 = np.pi / 2 - CAP_POLAR

    # reference profile (radius from the axis, height) relative to C: an arc, then down the neck
    arc_e = np.linspace(e0, np.radians(-40), 200)
    ref = np.stack([9.5 * np.cos(arc_e), 9.5 * np.sin(arc_e)], 1)
    ref = np.concatenate([ref, np.linspace(ref[-1], [4.5, shape.Y_CUT - C[1] - 6.0], 120)[1:]])
    seg = np.linalg.norm(np.diff(ref, axis=0), axis=1)
    cum = np.concatenate([[0], np.cumsum(seg)])
    M = int(Nr * 1.6)
    s = np.linspace(0, cum[-1], M)
    refp = np.stack([np.interp(s, cum, ref[:, 0]), np.interp(s, cum, ref[:, 1])], 1)
    elev = np.arctan2(refp[:, 1], refp[:, 0])  # decreasing

    # fine samples
    PH, EL = np.meshgrid(phis[:Nc], elev, indexing="ij")  # (Nc, M)
    D = _dirs(PH, EL).reshape(-1, 3)
    t_f = _raycast(shape, C, D, iters=8, tol=1e-3).reshape(Nc, M)
    P_f = C + t_f[..., None] * D.reshape(Nc, M, 3)

    # corner with the neck cut: a horizontal ray in the column's half-plane at the cut height
    hd = np.stack([np.sin(phis[:Nc]), np.zeros(Nc), np.cos(phis[:Nc])], 1)
    o = np.array([C[0], shape.Y_CUT, C[2]])
    body = type("_Body", (), {"sdf": staticmethod(shape.sdf_body)})
    tc = _raycast(body, o, hd, t_lo=0.5, t_hi=20.0, iters=10, tol=1e-4)
    corner = o + tc[:, None] * hd
    e_hi = np.arctan2(corner[:, 1] - C[1], np.hypot(corner[:, 0] - C[0], corner[:, 2] - C[2]))
    k_last = np.sum(elev[None, :] > e_hi[:, None], axis=1) - 1
    assert np.all(k_last < M - 1) and np.all(k_last > M // 2), "ring sampling misses the neck cut"

    # per-column weighted arc length -> row elevations.  The arc length is measured on the
    # column profile smoothed along the column (small cavities such as the nostrils must not
    # shift all the rows below them) and the resulting row fractions are smoothed across
    # columns, so that rows stay aligned between neighbouring columns (no sheared slivers).
    lam = np.empty((Nc, Nr))
    targets = np.arange(Nr) / Nr
    Ps = ndimage.gaussian_filter1d(P_f, 2.0, axis=1, mode="nearest")
    for j in range(Nc):
        k = k_last[j]
        pts = np.concatenate([Ps[j, : k + 1], corner[j : j + 1]])
        ee = np.concatenate([elev[: k + 1], [e_hi[j]]])
        mid = 0.5 * (pts[1:] + pts[:-1])
        L = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1) * _face_weight(mid))])
        L /= L[-1]
        lam[j] = (e0 - np.interp(targets, L, ee)) / (e0 - e_hi[j])
    lam = ndimage.gaussian_filter1d(lam, 2.0, axis=0, mode="wrap")
    rows_e = e0 - lam * (e0 - e_hi[:, None])
    rows_tg = np.stack([np.interp(-rows_e[j], -elev, t_f[j]) for j in range(Nc)])
    PH2 = np.broadcast_to(phis[:Nc, None], (Nc, Nr))
    D2 = _dirs(PH2, rows_e).reshape(-1, 3)
    t2 = _raycast_bracketed(shape, C, D2, rows_tg.ravel(), half=0.4, iters=6)
    ring = np.empty((Nr + 1, Nc + 1, 3))
    ring[:Nr, :Nc] = (C + t2[:, None] * D2).reshape(Nc, Nr, 3).transpose(1, 0, 2)
    ring[Nr, :Nc] = corner
    ring[:, Nc] = ring[:, 0]
    ringP = ring.reshape(-1, 3)
    a, b, c, d = _grid_tris(Nr, Nc)
    ringT = _split_quads(ringP, a, b, c, d)
    ringT = _orient_outward(ringP, ringT, C)

    # top cap: boundary = ring row 0 (directions at polar angle CAP_POLAR around +y)
    Kt = 22
    sin0 = np.sin(CAP_POLAR)
    inner = _disc_points(phis[:Nc], Kt, scale_fn=lambda r: np.sin(r * CAP_POLAR) / sin0)
    bnd = np.stack([np.sin(phis[:Nc]), np.cos(phis[:Nc])], 1)
    q = np.concatenate([bnd, inner])
    capT = spatial.Delaunay(q).simplices
    r = np.linalg.norm(inner, axis=1)
    ph = np.arctan2(inner[:, 0], inner[:, 1])
    g = r * CAP_POLAR
    di = np.stack([np.sin(g) * np.sin(ph), np.cos(g), np.sin(g) * np.cos(ph)], 1)
    ti = _raycast(shape, C, di, iters=10)
    capP = np.concatenate([ring[0, :Nc], C + ti[:, None] * di])
    capT = _orient_outward(capP, capT, C)

    # bottom cap: flat, boundary = ring row Nr
    cen = corner.mean(0)
    rel = corner - cen
    ang = np.arctan2(rel[:, 0], rel[:, 2])
    rad = np.hypot(rel[:, 0], rel[:, 2])
    order = np.argsort(ang)
    Kb = 13
    innerb = _disc_points(phis[:Nc], Kb, warp=False)
    bndb = np.stack([np.sin(ang), np.cos(ang)], 1)
    qb = np.concatenate([bndb, innerb])
    botT = spatial.Delaunay(qb).simplices
    rb = np.linalg.norm(innerb, axis=1)
    ab = np.arctan2(innerb[:, 0], innerb[:, 1])
    radi = np.interp(ab, ang[order], rad[order], period=2 * np.pi)
    pb = np.stack([cen[0] + rb * radi * np.sin(ab), np.full_like(rb, shape.Y_CUT), cen[2] + rb * radi * np.cos(ab)], 1)
    botP = np.concatenate([corner, pb])
    botT = _orient_outward(botP, botT, lambda c_: np.tile([0.0, -1.0, 0.0], (len(c_), 1)))
    return {"ring": (ringP, ringT), "top_cap": (capP, capT), "bottom_cap": (botP, botT)}, ring


# ----------------------------------------------------------------------------------------------
# ears: thin closed shells
# ----------------------------------------------------------------------------------------------

# outline of the (subject's left, +x) ear flap in its own plane: a = backward along the flap,
# b = up along the ear, centimetres from the root point (which is buried in the head).
_EAR_OUTLINE = np.array([
    (-0.35, 2.3), (0.45, 3.25), (1.5, 3.55), (2.55, 3.15), (3.2, 2.1), (3.2, 0.8), (2.75, -0.45),
    (2.15, -1.6), (1.5, -2.55), (0.75, -2.8), (0.1, -2.4), (-0.45, -1.4), (-0.8, 0.0),
    (-0.75, 1.3),
])
EAR_HALF_THICKNESS = 0.13  # cm: the flap is 2.6 mm thick
EAR_PROTRUSION = np.radians(27.0)
EAR_TILT = np.radians(12.0)
N_EAR_THETA = 72
N_EAR_IN = 14
N_EAR_RIM = 5
EAR_RIM_RADIUS = 0.15  # rounding of the rim, cm


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def _ear_outline(n):
    """n points on the closed outline at equal arc length (periodic Catmull-Rom spline)."""
    c = _EAR_OUTLINE
    m = len(c)
    u = np.linspace(0, m, 40 * m, endpoint=False)
    i = np.floor(u).astype(int)
    t = (u - i)[:, None]
    p0, p1, p2, p3 = c[(i - 1) % m], c[i % m], c[(i + 1) % m], c[(i + 2) % m]
    fine = 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2 + (-p0 + 3 * p1 - 3 * p2 + p3) * t**3)
    seg = np.linalg.norm(np.diff(np.concatenate([fine, fine[:1]]), axis=0), axis=1)
    cum = np.concatenate([[0], np.cumsum(seg)])
    s = np.arange(n) / n * cum[-1]
    closed = np.concatenate([fine, fine[:1]])
    return np.stack([np.interp(s, cum, closed[:, 0]), np.interp(s, cum, closed[:, 1])], 1)


def _ear_frame(shape):
    """Root point and axes (e_a backward along the flap, e_b up, e_n outward) of the +x ear."""
    o = np.array([0.0, 0.45, -0.75])
    t = _raycast(shape, o, np.array([[1.0, 0.0, 0.0]]), iters=30)[0]
    root = o + (t - 0.3) * np.array([1.0, 0.0, 0.0])
    ps, tau = EAR_PROTRUSION, EAR_TILT
    ea0 = np.array([np.sin(ps), 0.0, -np.cos(ps)])
    y = np.array([0.0, 1.0, 0.0])
    eb = np.cos(tau) * y + np.sin(tau) * ea0
    ea = np.cos(tau) * ea0 - np.sin(tau) * y
    en = np.cross(ea, eb)
    return root, ea, eb, en


def _ear_mid(a, b):
    """Out-of-plane offset of the flap's mid-surface (flare away from the head) and its
    derivatives."""
    ap = np.maximum(a, 0.0)
    w = 0.08 * ap**2
    return w, 0.16 * ap, np.zeros_like(b)


def _ear_thickness(a, b, d_edge):
    """Half thickness (front = lateral side, back = medial side) in cm of the flap at local
    (a, b) and distance ``d_edge`` from the outline: 1.3 mm each side, a rolled helix rim on the
    front along the upper and back edge, a thicker lobe."""
    h = EAR_HALF_THICKNESS
    helix = _smoothstep(-1.6, -0.6, b) * np.exp(-(((d_edge - 0.32) / 0.2) ** 2))
    lobe = _smoothstep(-1.2, -2.0, b)
    front = h + 0.11 * helix + 0.05 * lobe
    back = h + 0.04 * helix + 0.05 * lobe
    return front, back


def _build_ear(shape):
    """Closed thin shell for the +x ear: front (lateral) and back (medial) sheets joined at the
    rounded rim.  Returns (front_P, front_T, back_P, back_T, info)."""
    root, ea, eb, en = _ear_frame(shape)
    L = _ear_outline(N_EAR_THETA)  # (nt, 2)
    R = np.linalg.norm(L, axis=1)
    rho0 = 1.0 - EAR_RIM_RADIUS / R
    sig = np.arange(1, N_EAR_IN + 1) / N_EAR_IN
    psi = np.arange(1, N_EAR_RIM + 1) / N_EAR_RIM * (np.pi / 2)
    rho = np.concatenate([sig[:, None] * rho0[None, :], rho0[None, :] + (1 - rho0)[None, :] * np.sin(psi)[:, None]])
    fade = np.concatenate([np.ones(N_EAR_IN), np.cos(psi)])[:, None] * np.ones_like(rho)
    fade[-1] = 0.0
    a = rho * L[None, :, 0]
    b = rho * L[None, :, 1]
    d_edge = np.maximum((1 - rho) * R[None, :], EAR_RIM_RADIUS)
    w, wa, wb = _ear_mid(a, b)
    mid = root + a[..., None] * ea + b[..., None] * eb + w[..., None] * en
    nm = en - wa[..., None] * ea - wb[..., None] * eb
    nm /= np.linalg.norm(nm, axis=-1, keepdims=True)
    hf, hb = _ear_thickness(a, b, d_edge)
    front = mid + (hf * fade)[..., None] * nm
    back = mid - (hb * fade)[..., None] * nm
    hf0, hb0 = _ear_thickness(np.zeros(1), np.zeros(1), np.full(1, 3.0))
    pole_f = root + hf0[0] * en
    pole_b = root - hb0[0] * en
    nr, nt = rho.shape
    # triangles: pole fan + quads between rings (ring r vertex j -> 1 + r * nt + j)
    j = np.arange(nt)
    j1 = (j + 1) % nt
    fan = np.stack([np.zeros(nt, int), 1 + j, 1 + j1], 1)
    r = np.arange(nr - 1)[:, None]
    a_, b_ = 1 + r * nt + j, 1 + r * nt + j1
    c_, d_ = 1 + (r + 1) * nt + j1, 1 + (r + 1) * nt + j
    quads = np.concatenate([np.stack([a_, d_, c_], -1).reshape(-1, 3), np.stack([a_, c_, b_], -1).reshape(-1, 3)])
    T = np.concatenate([fan, quads])
    Pf = np.concatenate([pole_f[None], front.reshape(-1, 3)])
    Pb = np.concatenate([pole_b[None], back.reshape(-1, 3)])
    Tf = _orient_outward(Pf, T, lambda c_: np.tile(en, (len(c_), 1)))
    Tb = _orient_outward(Pb, T, lambda c_: np.tile(-en, (len(c_), 1)))
    info = dict(root=root, ea=ea, eb=eb, en=en)
    return Pf, Tf, Pb, Tb, info


def _ear_point(info, a, b):
    """Mid-surface point of the +x ear at local (a, b)."""
    w, _, _ = _ear_mid(np.asarray(a, float), np.asarray(b, float))
    return info["root"] + a * info["ea"] + b * info["eb"] + w * info["en"]


# ----------------------------------------------------------------------------------------------
# UV layout
# ----------------------------------------------------------------------------------------------


def _boundary_vertices(T):
    e = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    es = np.sort(e, axis=1)
    u, c = np.unique(es, axis=0, return_counts=True)
    return np.unique(u[c == 1])


def _lscm(P, T):
    """Least-squares conformal map (Levy et al. 2002) of a disc-like patch; orientation
    preserving (UV triangles counter-clockwise when the 3-D triangles are counter-clockwise seen
    along their normal).  Returns (n, 2) UVs in the units of P."""
    n, m = len(P), len(T)
    p0, p1, p2 = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    nrm = np.cross(e1, e2)
    a2 = np.linalg.norm(nrm, axis=1)  # twice the area
    x = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    y = np.cross(nrm / a2[:, None], x)
    q = np.zeros((m, 3, 2))
    q[:, 1, 0] = np.linalg.norm(e1, axis=1)
    q[:, 2, 0] = np.einsum("ij,ij->i", e2, x)
    q[:, 2, 1] = np.einsum("ij,ij->i", e2, y)
    # gradients of the barycentric coordinates: ((y_j+1 - y_j+2), (x_j+2 - x_j+1)) / 2A
    qa, qb = np.roll(q, -1, axis=1), np.roll(q, -2, axis=1)
    gx = (qa[..., 1] - qb[..., 1]) / a2[:, None]
    gy = (qb[..., 0] - qa[..., 0]) / a2[:, None]
    w = np.sqrt(0.5 * a2)[:, None]
    ar, ai = gx * w, gy * w  # c_j = a + i b ; residual sum_j c_j U_j
    rows_r = np.repeat(np.arange(m), 3)
    cols = T.ravel()
    # real part: sum a u - b v ; imaginary part: sum b u + a v
    data = np.concatenate([ar.ravel(), -ai.ravel(), ai.ravel(), ar.ravel()])
    rr = np.concatenate([rows_r, rows_r, rows_r + m, rows_r + m])
    cc = np.concatenate([cols, cols + n, cols, cols + n])
    A = sparse.csr_matrix((data, (rr, cc)), shape=(2 * m, 2 * n))
    # pins: two far-apart boundary vertices
    bnd = _boundary_vertices(T)
    bp = P[bnd]
    i0 = bnd[np.argmax(np.linalg.norm(bp - bp.mean(0), axis=1))]
    i1 = bnd[np.argmax(np.linalg.norm(bp - P[i0], axis=1))]
    dist = float(np.linalg.norm(P[i1] - P[i0]))
    pins = np.array([i0, i1, i0 + n, i1 + n])
    pinv = np.array([0.0, dist, 0.0, 0.0])
    free = np.setdiff1d(np.arange(2 * n), pins)
    Af = A[:, free]
    rhs = -(A[:, pins] @ pinv)
    lu = splu((Af.T @ Af).tocsc(), permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True))
    sol = lu.solve(Af.T @ rhs)
    x_all = np.empty(2 * n)
    x_all[free] = sol
    x_all[pins] = pinv
    return np.stack([x_all[:n], x_all[n:]], 1)


def _signed_uv_area(uv, T):
    a, b, c = uv[T[:, 0]], uv[T[:, 1]], uv[T[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))


def _tri_areas(P, T):
    return 0.5 * np.linalg.norm(np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]), axis=1)


def _arap(P, T, uv0, iters=12):
    """As-rigid-as-possible parameterisation (Liu et al. 2008), local/global iterations from
    ``uv0``.  Keeps the triangles' orientation of ``uv0`` (which must be counter-clockwise)."""
    n, m = len(P), len(T)
    p0, p1, p2 = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    nrm = np.cross(e1, e2)
    a2 = np.linalg.norm(nrm, axis=1)
    x = e1 / np.linalg.norm(e1, axis=1, keepdims=True)
    y = np.cross(nrm / a2[:, None], x)
    q = np.zeros((m, 3, 2))
    q[:, 1, 0] = np.linalg.norm(e1, axis=1)
    q[:, 2, 0] = np.einsum("ij,ij->i", e2, x)
    q[:, 2, 1] = np.einsum("ij,ij->i", e2, y)
    # cotangent of the angle at each corner
    cot = np.empty((m, 3))
    for k in range(3):
        a = q[:, (k + 1) % 3] - q[:, k]
        b = q[:, (k + 2) % 3] - q[:, k]
        cot[:, k] = (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]) / (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    # half-edges (i, j) opposite corner k
    I = np.concatenate([T[:, 1], T[:, 2], T[:, 0]])
    J = np.concatenate([T[:, 2], T[:, 0], T[:, 1]])
    W = np.concatenate([cot[:, 0], cot[:, 1], cot[:, 2]])
    Lm = sparse.coo_matrix((np.concatenate([W, W, -W, -W]), (np.concatenate([I, J, I, J]), np.concatenate([I, J, J, I]))), shape=(n, n)).tocsc()
    # pin vertex 0 (fixes the translation)
    keep = np.arange(1, n)
    lu = splu(Lm[keep][:, keep].tocsc(), permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True))
    qi = np.concatenate([q[:, 1], q[:, 2], q[:, 0]])
    qj = np.concatenate([q[:, 2], q[:, 0], q[:, 1]])
    dq = qi - qj  # (3m, 2)
    Eq = np.stack([q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]], -1)  # (m, 2, 2) columns
    Eq_inv = np.linalg.inv(Eq)
    uv = uv0.copy()
    col0 = np.asarray(Lm[keep][:, [0]].todense()).ravel()
    for _ in range(iters):
        Euv = np.stack([uv[T[:, 1]] - uv[T[:, 0]], uv[T[:, 2]] - uv[T[:, 0]]], -1)
        Jt = Euv @ Eq_inv
        th = np.arctan2(Jt[:, 1, 0] - Jt[:, 0, 1], Jt[:, 0, 0] + Jt[:, 1, 1])
        c3, s3 = np.tile(np.cos(th), 3), np.tile(np.sin(th), 3)
        rx = (c3 * dq[:, 0] - s3 * dq[:, 1]) * W
        ry = (s3 * dq[:, 0] + c3 * dq[:, 1]) * W
        bx = np.bincount(I, rx, n) - np.bincount(J, rx, n)
        by = np.bincount(I, ry, n) - np.bincount(J, ry, n)
        uv[keep, 0] = lu.solve(bx[keep] - col0 * uv[0, 0])
        uv[keep, 1] = lu.solve(by[keep] - col0 * uv[0, 1])
    return uv


def _ring_init_uv(ring):
    """Arc-length unrolling of the ring grid (rows x cols+1, seam column duplicated): u along
    the rows from the front midline, v along the columns from the eye row."""
    Nr1, Nc1 = ring.shape[:2]
    jf = (Nc1 - 1) // 2  # front column (azimuth 0)
    du = np.linalg.norm(np.diff(ring, axis=1), axis=2)
    u = np.concatenate([np.zeros((Nr1, 1)), np.cumsum(du, axis=1)], 1)
    u -= u[:, jf : jf + 1]
    dv = np.linalg.norm(np.diff(ring, axis=0), axis=2)
    v = -np.concatenate([np.zeros((1, Nc1)), np.cumsum(dv, axis=0)], 0)
    iref = np.argmin(np.abs(ring[:, jf, 1] - 1.5))
    v -= v[iref : iref + 1]
    return np.stack([u, v], -1).reshape(-1, 2)


def _rotate_uv(uv, ang):
    c, s = np.cos(ang), np.sin(ang)
    return uv @ np.array([[c, s], [-s, c]])


def _min_bbox_angle(uv, angles):
    best, best_a = np.inf, 0.0
    for a in angles:
        r = _rotate_uv(uv, a)
        ext = r.max(0) - r.min(0)
        if ext[0] * ext[1] < best:
            best, best_a = ext[0] * ext[1], a
    return best_a


def _skyline_pack(sizes, W, H):
    """Bottom-left skyline packing of rectangles (w, h) in order into [0, W] x [0, H] (y grows
    downward from the top).  Returns positions or None if they do not fit."""
    sky = [(0.0, W, 0.0)]  # segments (x, width, y)
    out = []
    for w, h in sizes:
        best = None
        for i, (x0, _, _) in enumerate(sky):
            if x0 + w > W + 1e-12:
                break
            y, xe = 0.0, x0 + w
            for x1, w1, y1 in sky[i:]:
                if x1 >= xe - 1e-12:
                    break
                y = max(y, y1)
            if y + h <= H + 1e-12 and (best is None or (y, x0) < (best[1], best[0])):
                best = (x0, y)
        if best is None:
            return None
        x0, y = best
        out.append(best)
        new = []
        for x1, w1, y1 in sky:
            a, b = x1, x1 + w1
            if b <= x0 or a >= x0 + w:
                new.append((x1, w1, y1))
                continue
            if a < x0:
                new.append((a, x0 - a, y1))
            if b > x0 + w:
                new.append((x0 + w, b - x0 - w, y1))
        new.append((x0, w, y + h))
        new.sort()
        merged = []
        for seg in new:
            if merged and abs(merged[-1][2] - seg[2]) < 1e-12 and abs(merged[-1][0] + merged[-1][1] - seg[0]) < 1e-12:
                merged[-1] = (merged[-1][0], merged[-1][1] + seg[1], seg[2])
            else:
                merged.append(seg)
        sky = merged
    return out


def _pack_islands(uvs, rel_density):
    """Scale (common texel density times ``rel_density``), and pack islands (UVs in
    centimetres, already oriented) into [0, 1]^2 with gutters; returns the packed UVs and the
    scale (UV units per centimetre at relative density 1)."""
    G, M = GUTTER_UV, MARGIN_UV
    ext = [u.max(0) - u.min(0) for u in uvs]
    order = sorted(range(len(uvs)), key=lambda i: -ext[i][1] * rel_density[i] if i else -np.inf)
    scale = (1 - 2 * M) / max(e[0] * d for e, d in zip(ext, rel_density))
    for _ in range(200):
        sizes = [(ext[i][0] * rel_density[i] * scale + G, ext[i][1] * rel_density[i] * scale + G) for i in order]
        pos = _skyline_pack(sizes, 1 - 2 * M + G, 1 - 2 * M + G)
        if pos is not None:
            break
        scale *= 0.99
    out = [None] * len(uvs)
    for (x, y), i in zip(pos, order):
        u = (uvs[i] - uvs[i].min(0)) * rel_density[i] * scale
        hgt = ext[i][1] * rel_density[i] * scale
        # image-style y (down from the top) -> v up
        u[:, 0] += M - G / 2 + x + G / 2
        u[:, 1] += 1 - (M - G / 2 + y + G / 2) - hgt
        out[i] = u
    return out, scale


# ----------------------------------------------------------------------------------------------
# mesh assembly
# ----------------------------------------------------------------------------------------------


def _vertex_normals(P, T, group):
    """Angle-weighted vertex normals, shared by vertices with the same ``group`` id."""
    fn = np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-30)
    ng = group.max() + 1
    acc = np.zeros((ng, 3))
    for k in range(3):
        a = P[T[:, (k + 1) % 3]] - P[T[:, k]]
        b = P[T[:, (k + 2) % 3]] - P[T[:, k]]
        cosang = np.einsum("ij,ij->i", a, b) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-30)
        w = np.arccos(np.clip(cosang, -1, 1))
        for c in range(3):
            acc[:, c] += np.bincount(group[T[:, k]], fn[:, c] * w, ng)
    n = acc[group]
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


@functools.lru_cache(maxsize=2)
def _geometry():
    """Mesh, packed UVs, islands and landmarks (independent of the texture size and seed)."""
    shape = _Shape()
    parts, ring = _build_head_surface(shape)
    Pf, Tf, Pb, Tb, ear = _build_ear(shape)
    mirror = np.array([-1.0, 1.0, 1.0])
    parts["left_ear_front"] = (Pf, Tf)
    parts["left_ear_back"] = (Pb, Tb)
    parts["right_ear_front"] = (Pf * mirror, Tf[:, ::-1].copy())
    parts["right_ear_back"] = (Pb * mirror, Tb[:, ::-1].copy())

    # flatten the islands (centimetres), orient them (counter-clockwise, tight bounding box;
    # the ring with the head's up along +v)
    uvs = []
    for name in ISLANDS:
        P, T = parts[name]
        if name == "ring":
            uv = _ring_init_uv(ring)
            if np.sum(_signed_uv_area(uv, T) < 0) > len(T) // 2:
                uv[:, 0] *= -1
            uv = _arap(P, T, uv, iters=8)
            Nc1 = N_COLS + 1
            top = uv[:Nc1].mean(0)
            bot = uv[-Nc1:].mean(0)
            d = top - bot
            base = np.arctan2(d[0], d[1])  # rotating by this brings d onto +v
            uv = _rotate_uv(uv, -base)
            uv = _rotate_uv(uv, _min_bbox_angle(uv, np.radians(np.linspace(-6, 6, 25))))
        else:
            uv = _lscm(P, T)
            uv = _rotate_uv(uv, _min_bbox_angle(uv, np.radians(np.arange(0, 180, 3.0))))
        if np.sum(_signed_uv_area(uv, T) < 0) > len(T) // 2:  # mirrored solution: flip u
            uv[:, 0] *= -1
        uvs.append(uv)
    # common density: every island gets the ring's UV-area / 3-D-area ratio
    rel = []
    for name, uv in zip(ISLANDS, uvs):
        P, T = parts[name]
        k = np.sqrt(_tri_areas(P, T).sum() / np.abs(_signed_uv_area(uv, T)).sum())
        rel.append(k * (0.5 if name == "bottom_cap" else 1.0))
    packed, scale = _pack_islands(uvs, rel)

    # assemble
    Ps, Ts, UVs, isl, groups = [], [], [], [], []
    base = 0
    for k, name in enumerate(ISLANDS):
        P, T = parts[name]
        Ps.append(P)
        Ts.append(T + base)
        UVs.append(packed[k])
        isl.append(np.full(len(T), k, np.int8))
        base += len(P)
    P = np.concatenate(Ps)
    T = np.concatenate(Ts)
    UV = np.concatenate(UVs)
    island = np.concatenate(isl)
    # normals: smooth across UV seams (vertices at the same position share a normal), but the
    # flat bottom cut keeps its own (sharp edge)
    key = np.round(P, 6)
    bottom = np.zeros(len(P), bool)
    b0 = sum(len(parts[n][0]) for n in ISLANDS[:2])
    bottom[b0 : b0 + len(parts["bottom_cap"][0])] = True
    key = np.concatenate([key, bottom[:, None].astype(float)], 1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    N = _vertex_normals(P, T, group.ravel())

    # landmarks
    C = shape.C
    e = shape.EYE
    targets = {
        "crown": C + [0, 1, 0],
        "forehead": [0, 6.0, 9.0],
        "left_eye": [e[0], e[1], e[2] + shape.EYE_R],
        "right_eye": [-e[0], e[1], e[2] + shape.EYE_R],
        "left_eye_inner_socket": [1.75, 1.75, 8.0],
        "right_eye_inner_socket": [-1.75, 1.75, 8.0],
        "left_nostril": shape.NOSTRIL,
        "right_nostril": shape.NOSTRIL * mirror,
        "lips": [0, shape.STOMION_Y, 9.5],
        "left_cheek": [4.0, -1.2, 7.0],
        "right_cheek": [-4.0, -1.2, 7.0],
        "chin": [0, -8.4, 9.5],
        "neck": [0, -14.0, 5.0],
    }
    dirs = np.array([np.asarray(v, float) - C for v in targets.values()])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    th = _raycast(shape, C, dirs, iters=12, tol=1e-5)
    lm = {"head_centre": C.copy()}
    lm.update({k: C + t * d for k, t, d in zip(targets, th, dirs)})
    lm.update({
        "nose_tip": P[np.argmax(np.where((np.abs(P[:, 0]) < 1) & (P[:, 1] > -3) & (P[:, 1] < 0), P[:, 2], -np.inf))],
        "left_ear": _ear_point(ear, 2.2, 0.6),
        "right_ear": _ear_point(ear, 2.2, 0.6) * mirror,
        "left_ear_root": ear["root"].copy(),
        "right_ear_root": ear["root"] * mirror,
    })
    lm = {k: np.asarray(v, np.float32) for k, v in lm.items()}
    return dict(P=P, N=N, UV=UV, T=T, island=island, scale=scale, landmarks=lm, shape=shape, ear=ear)


# ----------------------------------------------------------------------------------------------
# texture space
# ----------------------------------------------------------------------------------------------


def _rasterize_uv(uv, T, W, H):
    """Which triangle covers each texel centre, and its barycentric coordinates.

    Texel (row, col) has its centre at u = (col + .5) / W, v = 1 - (row + .5) / H.  Returns
    tri (H, W) int32 (-1: gutter) and bary (H, W, 3) float32."""
    x = uv[:, 0] * W - 0.5  # texel-centre coordinates (col)
    y = (1.0 - uv[:, 1]) * H - 0.5  # (row)
    tx, ty = x[T], y[T]
    c0 = np.clip(np.ceil(tx.min(1) - 1e-9).astype(int), 0, W - 1)
    c1 = np.clip(np.floor(tx.max(1) + 1e-9).astype(int), 0, W - 1)
    r0 = np.clip(np.ceil(ty.min(1) - 1e-9).astype(int), 0, H - 1)
    r1 = np.clip(np.floor(ty.max(1) + 1e-9).astype(int), 0, H - 1)
    nw, nh = c1 - c0 + 1, r1 - r0 + 1
    tri = np.full(H * W, -1, np.int32)
    bary = np.zeros((H * W, 3), np.float32)
    ok = (nw > 0) & (nh > 0)
    sz = np.maximum(nw, nh)
    d = (tx[:, 1] - tx[:, 0]) * (ty[:, 2] - ty[:, 0]) - (tx[:, 2] - tx[:, 0]) * (ty[:, 1] - ty[:, 0])
    for s in np.unique(sz[ok]):
        sel = np.nonzero(ok & (sz == s))[0]
        oy, ox = np.divmod(np.arange(s * s), s)
        for ch in np.array_split(sel, max(1, len(sel) * s * s // 1_500_000 + 1)):
            cx = c0[ch, None] + ox[None]
            cy = r0[ch, None] + oy[None]
            ax, ay = tx[ch, 0, None], ty[ch, 0, None]
            dd = d[ch, None]
            w1 = ((cx - ax) * (ty[ch, 2, None] - ay) - (tx[ch, 2, None] - ax) * (cy - ay)) / dd
            w2 = ((tx[ch, 1, None] - ax) * (cy - ay) - (cx - ax) * (ty[ch, 1, None] - ay)) / dd
            w0 = 1.0 - w1 - w2
            ins = (w0 >= -1e-6) & (w1 >= -1e-6) & (w2 >= -1e-6) & (cx <= c1[ch, None]) & (cy <= r1[ch, None])
            pix = (cy * W + cx)[ins]
            tri[pix] = np.broadcast_to(ch[:, None], ins.shape)[ins]
            bary[pix] = np.stack([w0[ins], w1[ins], w2[ins]], 1)
    return tri.reshape(H, W), bary.reshape(H, W, 3)


def _value_noise3(P, cell, rng, smooth=1.0):
    """Smooth 3-D value noise (zero mean, ~unit std) at points P (n, 3), feature size ~cell."""
    lo = P.min(0) - 2 * cell
    dims = np.ceil((P.max(0) + 2 * cell - lo) / cell).astype(int) + 1
    lat = rng.standard_normal(tuple(dims)).astype(np.float32)
    if smooth > 0:
        lat = ndimage.gaussian_filter(lat, smooth, mode="wrap")
    lat /= lat.std() + 1e-12
    coords = ((P - lo) / cell).T
    return ndimage.map_coordinates(lat, coords, order=1, mode="nearest")


def _splat(H, W, rows, cols, vals):
    """Bilinear splat of point impulses into an (H, W) image."""
    img = np.zeros(H * W, np.float64)
    r0 = np.floor(rows).astype(int)
    c0 = np.floor(cols).astype(int)
    fr, fc = rows - r0, cols - c0
    for dr, dc, w in ((0, 0, (1 - fr) * (1 - fc)), (0, 1, (1 - fr) * fc), (1, 0, fr * (1 - fc)), (1, 1, fr * fc)):
        rr, cc = r0 + dr, c0 + dc
        ok = (rr >= 0) & (rr < H) & (cc >= 0) & (cc < W)
        img += np.bincount(rr[ok] * W + cc[ok], (vals * w)[ok], H * W)
    return img.reshape(H, W)


def _jittered_points(H, W, spacing, rng):
    """One random point per (spacing x spacing)-texel cell."""
    ny, nx = int(np.ceil(H / spacing)), int(np.ceil(W / spacing))
    gy, gx = np.mgrid[0:ny, 0:nx]
    rows = (gy.ravel() + rng.random(gy.size)) * spacing - 0.5
    cols = (gx.ravel() + rng.random(gx.size)) * spacing - 0.5
    keep = (rows >= 0) & (rows <= H - 1) & (cols >= 0) & (cols <= W - 1)
    return rows[keep], cols[keep]


def _sstep(e0, e1, x):
    return _smoothstep(e0, e1, x)
