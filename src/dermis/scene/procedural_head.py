"""The built-in default scene's geometry and textures: a procedural head-and-neck bust.

Everything here is generated from code (numpy/scipy only, no files, no GL), deterministically for
a given seed, so that ``dermis render`` with no arguments gives a meaningful skin image anywhere.

Geometry (scene units are centimetres, ``mm_per_unit = 10``; y up, the face looks toward +z, the
subject's left is +x):

* The head and neck are one smooth implicit surface: smooth unions of ellipsoids / capsules
  (cranium, forehead, cheeks, jaw, chin, lips, nose, brow ridge, sterno-cleido-mastoid muscles,
  neck) minus smooth subtractions (eye sockets, nostrils), with closed eyelids
  (eyeball spheres) and a flat cut at the bottom of the neck.  It is star-shaped around a centre
  ``C`` inside the head, so it is meshed by casting rays from ``C``.
* Meshing avoids poles and grazing rays: a *ring* grid (columns at fixed azimuth, denser on the
  face; rows re-sampled per column at equal weighted arc length, denser on the face) from the
  hairline down to the neck cut, a *top cap* and a flat *bottom cap* triangulated (Delaunay) in a
  normalised disc whose boundary is exactly the ring's first / last row.
* The ears are separate, genuinely thin closed shells (about 2.6 mm thick flap, up to ~4 mm at
  the helix rim and lobe, rounded edges) whose front edge is buried in the side of the head (they
  interpenetrate it, like a sculpt base mesh), so they transmit light when back-lit.
* Concave parts: eye sockets (the closed lids lie ~7 mm and the inner corners ~13 mm inside the
  convex hull), nostrils (tunnels toward ``C``, ~6 mm deeper than their rim).

UV layout (unique, for texture-space diffusion): xatlas charts (dermis.geometry.atlas: charts,
least-squares conformal parameterisation, packing) of the welded surface, packed for 1024^2 with
``ATLAS_PADDING_TEXELS`` of padding around every chart (>= 12 texels between charts), all charts
at one texel density (~0.5 mm of skin per texel at 1024^2). Charts may be mirrored (tangent
handedness w = -1 there); the normal map is encoded in the frame the renderer rebuilds either way.
``islands`` labels each triangle with its part (``PARTS``: the ring of the head and neck, the top
cap, the bottom cut, the front / back sheet of each ear), which the texture painter uses as masks.
The gutters of every texture are filled with the value of the nearest chart texel (dilation), so
bilinear filtering and blurs never pick up black.

Textures (row 0 = top of the image, i.e. texel (row, col) is at u = (col + .5) / W,
v = 1 - (row + .5) / H; v = 0 is the bottom row, the OpenGL convention used by the UVs):

* ``albedo``: linear RGB, fair skin (mean ~ (0.45, 0.25, 0.17)) with low-frequency melanin and
  redness blotches (3-D noise, so they are continuous across UV seams), redness on cheeks, nose
  and ears, freckles (~1 mm spots, mostly on nose and cheeks), eyebrows, closed eyelids with a
  dark lash line, darker nostrils, red lips (~(0.45, 0.12, 0.10)).
* ``normal_map``: tangent-space (OpenGL: +x along +u, +y along +v, encoded n * 0.5 + 0.5) from a
  height field in millimetres: pores (dimples ~0.06 mm deep on a jittered grid
  ``pore_spacing_mm`` = 1.0 mm apart, ~100 per cm^2 -- the density of visible facial pores; at
  1024^2 a texel is ~0.52 mm, so finer spacings could not be represented), band-limited
  micro-relief (0.3-1 mm), forehead lines, crow's feet, lip lines, the closed-eyelid groove, the
  mouth line, labio-mental and naso-labial folds.  The perturbation is expressed in the frame
  the renderer rebuilds (dermis.scene.tangents: T = dP/du orthogonalised against N,
  B = cross(N, T), w = +1), exactly, using each triangle's UV Jacobian.
* ``specular``: intensity in [0, 1]: oily T-zone (forehead, nose, chin) and lips brighter,
  eyebrows and pores duller.

Landmarks (scene units): head_centre, crown, forehead, left/right_eye (closed lid),
left/right_eye_inner_socket, nose_tip, left/right_nostril (bottom of the nostril),
lips (mouth line), upper_lip, lower_lip, left/right_cheek, chin, neck (front),
left/right_ear (middle of the visible ear flap, inside it), left/right_ear_root (inside the head).

``build_default_head`` is cached (``functools.lru_cache``); the arrays it returns are read-only,
copy them before modifying.  Building takes about 1-2 s at 1024^2 (geometry ~1 s, textures
~1 s).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, spatial

from dermis.geometry.atlas import atlas_on_welded_surface
from dermis.geometry.rasterize import rasterize_uv

MM_PER_UNIT = 10.0
LABIOMENTAL_Y = -6.75  # height of the labio-mental fold (normal map), cm


def NASOLABIAL_X(y):
    """|x| of the naso-labial fold (normal map) at height y, cm."""
    t = np.clip((np.asarray(y, float) + 2.3) / -3.6, 0, 1)
    return 1.75 + 1.1 * t + 0.25 * t * t


PORE_SPACING_MM = 1.0
ATLAS_RESOLUTION = 1024  # texels per side the UV charts are packed for
ATLAS_PADDING_TEXELS = 6  # xatlas padding around every chart: >= 12 texels between charts at 1024^2


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
    islands: np.ndarray | None = None  # (M,) int8 part of each triangle (see PARTS)
    texel_mm: float = 0.0  # mean millimetres per texel of the skin islands at this texture size


PARTS = ("ring", "top_cap", "bottom_cap", "left_ear_front", "left_ear_back", "right_ear_front", "right_ear_back")
ISLANDS = PARTS  # former name (the parts were the UV islands before the layout came from xatlas)


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
    """Ellipsoid (optionally rotated: R = world -> local rows), approximate distance (Quilez)."""

    def __init__(self, c, r, R=None):
        self.c = np.asarray(c, np.float32)
        self.r = np.asarray(r, np.float32)
        self.R = None if R is None else np.asarray(R, np.float64)
        self.bound = float(np.max(self.r))
        self._c = [float(v) for v in self.c]
        self._ir = [1.0 / float(v) for v in self.r]
        self._R = None if R is None else [[float(v) for v in row] for row in self.R]

    def __call__(self, p):
        return self.xyz(p[:, 0], p[:, 1], p[:, 2])

    def xyz(self, x, y, z):
        cx, cy, cz = self._c
        x, y, z = x - cx, y - cy, z - cz
        if self._R is not None:
            (a, b, c), (d, e, f), (g, h, i) = self._R
            x, y, z = a * x + b * y + c * z, d * x + e * y + f * z, g * x + h * y + i * z
        ix, iy, iz = self._ir
        x, y, z = x * ix, y * iy, z * iz
        k0 = np.sqrt(x * x + y * y + z * z)
        x, y, z = x * ix, y * iy, z * iz
        k1 = np.sqrt(x * x + y * y + z * z)
        return k0 * (k0 - 1.0) / np.maximum(k1, 1e-12)


class _Capsule:
    """Segment a-b with a radius varying linearly from ra to rb (a round cone, approximately),
    optionally scaled per axis."""

    def __init__(self, a, b, ra, rb=None, scale=(1.0, 1.0, 1.0)):
        self.a = np.asarray(a, np.float32)
        self.b = np.asarray(b, np.float32)
        self.ra = float(ra)
        self.rb = float(ra if rb is None else rb)
        self.s = np.asarray(scale, np.float32)
        self.c = 0.5 * (self.a + self.b)
        self.bound = 0.5 * float(np.linalg.norm(self.b - self.a)) + max(self.ra, self.rb) * float(self.s.max())

    def __call__(self, p):
        return self.xyz(p[:, 0], p[:, 1], p[:, 2])

    def xyz(self, x, y, z):
        ax, ay, az = (float(v) for v in self.a)
        bx, by, bz = (float(v) - float(u) for v, u in zip(self.b, self.a))
        inv = 1.0 / (bx * bx + by * by + bz * bz)
        x, y, z = x - ax, y - ay, z - az
        h = np.clip((x * bx + y * by + z * bz) * inv, 0.0, 1.0)
        sx, sy, sz = (1.0 / float(v) for v in self.s)
        x, y, z = (x - h * bx) * sx, (y - h * by) * sy, (z - h * bz) * sz
        return np.sqrt(x * x + y * y + z * z) * float(self.s.min()) - (self.ra + (self.rb - self.ra) * h)


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
        add(E((0, -0.2, 3.0), (6.75, 4.6, 6.3)), 2.4)  # mid-face (zygomatic width)
        add(E((0, -5.2, 2.9), (4.75, 3.6, 5.6), _rot(pitch=0.3)), 2.2)  # jaw mass
        # neck (slightly elliptic, widening a little toward the base) and the
        # sterno-cleido-mastoid muscles
        add(Cap((0, -4.0, -1.7), (0, -30.0, -0.6), 5.55, 6.5, scale=(1.0, 1.0, 1.07)), 3.0)
        for s in (1, -1):
            add(Cap((s * 4.4, -3.0, -2.4), (s * 1.9, -24.0, 2.0), 1.05, 1.45), 2.2)
        for s in (1, -1):
            # jaw line (gonion -> chin)
            add(Cap((s * 4.65, -6.8, -0.3), (s * 1.4, -9.1, 6.6), 0.75, 0.75), 2.0)
            # cheekbones and cheeks
            add(E((s * 4.8, 0.4, 5.2), (1.8, 1.2, 2.0)), 1.6)
            add(E((s * 3.5, -2.1, 6.0), (2.2, 2.3, 2.45)), 2.4)
            # brow ridge
            add(E((s * 2.5, 3.15, 7.9), (2.4, 0.9, 1.4), _rot(yaw=s * 0.35)), 1.2)
        # chin
        add(E((0, -8.4, 7.7), (1.95, 1.75, 1.8)), 1.4)
        # mouth: muzzle and lips
        add(E((0, -4.6, 6.75), (3.1, 2.6, 2.3)), 1.6)
        add(E((0, -4.3, 8.62), (2.0, 0.56, 1.05), _rot(pitch=-0.25)), 0.55)
        add(E((0, -5.5, 8.48), (1.85, 0.6, 0.92), _rot(pitch=0.2)), 0.45)
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
            prim = E(self.C - t * ax, radii, _frame_from_axis(ax))
            sub(prim, k)
            return prim

        # nostrils
        self.nostrils = [cavity((s * self.NOSTRIL[0], self.NOSTRIL[1], self.NOSTRIL[2]), (0.27, 0.17, 0.7), 0.12) for s in (1, -1)]

    def sdf(self, p):
        """Signed distance-like function (negative inside) at points p (n, 3), in float32."""
        p = np.asarray(p, np.float32)
        x, y, z = (np.ascontiguousarray(p[:, k]) for k in range(3))
        return np.maximum(self._body(x, y, z), self.Y_CUT - y)

    def sdf_body(self, p):
        """The surface without the flat cut at the bottom of the neck."""
        p = np.asarray(p, np.float32)
        return self._body(*(np.ascontiguousarray(p[:, k]) for k in range(3)))

    def _body(self, x, y, z):
        if "_groups" not in self.__dict__:
            self._make_groups()
        glob, (gc, gr, gk, face) = self._groups
        d = self.base.xyz(x, y, z)
        for op, prim, k in glob:  # large masses: everywhere
            e = prim.xyz(x, y, z)
            d = _smin(d, e, k) if op == "u" else _smax(d, -e, k)
        # face features: only near the face (two-level culling with bounding spheres; a primitive
        # has no effect where it is farther than its smoothing width k)
        lim = gr + gk + np.abs(d)
        idx = np.nonzero((x - gc[0]) ** 2 + (y - gc[1]) ** 2 + (z - gc[2]) ** 2 < lim * lim)[0]
        if len(idx):
            xi, yi, zi, di = x[idx], y[idx], z[idx], d[idx]
            for op, prim, k in face:
                c = prim.c
                lim = 1.3 * prim.bound + k + np.abs(di)
                j = np.nonzero((xi - c[0]) ** 2 + (yi - c[1]) ** 2 + (zi - c[2]) ** 2 < lim * lim)[0]
                if len(j) == 0:
                    continue
                e = prim.xyz(xi[j], yi[j], zi[j])
                di[j] = _smin(di[j], e, k) if op == "u" else _smax(di[j], -e, k)
            d[idx] = di
        return d

    def _make_groups(self):
        """Large masses are evaluated everywhere, the face features inside a bounding sphere."""
        face_c = np.array([0.0, -1.5, 8.0], np.float32)
        glob, face = [], []
        for op in self.ops:
            prim = op[1]
            if np.linalg.norm(prim.c - face_c) + 1.3 * prim.bound < 9.5:
                face.append(op)
            else:
                glob.append(op)
        kmax = max(op[2] for op in face)
        self._groups = (glob, ([float(v) for v in face_c], 9.5, kmax, face))


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
    """Split the quads a-b-c-d (corners in cyclic order) along their shorter diagonal; the two
    triangles of every quad share the winding of the cycle a -> d -> c -> b (the global
    orientation is fixed afterwards by ``_orient_outward``)."""
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


def _disc_points(boundary_phis, K, scale_fn=None, warp=True):
    """Concentric rings in the unit disc (boundary excluded) for a cap triangulation; ring k of
    K has about len(boundary_phis) * scale_fn(k / K) points."""
    pts = [np.zeros((1, 2))]
    nb = len(boundary_phis)
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
    M = int(Nr * 1.4)
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
    # flare, plus a shallow concha bowl in front of the root
    g = 0.22 * np.exp(-(((a - 0.9) / 0.75) ** 2) - ((b + 0.35) / 1.1) ** 2)
    w = 0.08 * ap**2 - g
    wa = 0.16 * ap + g * 2 * (a - 0.9) / 0.75**2
    wb = g * 2 * (b + 0.35) / 1.1**2
    return w, wa, wb


def _ear_thickness(a, b, d_edge):
    """Half thickness (front = lateral side, back = medial side) in cm of the flap at local
    (a, b) and distance ``d_edge`` from the outline: 1.3 mm each side, a rolled helix rim on the
    front along the upper and back edge, a thicker lobe."""
    h = EAR_HALF_THICKNESS
    helix = _smoothstep(-1.6, -0.6, b) * np.exp(-(((d_edge - 0.32) / 0.2) ** 2))
    lobe = _smoothstep(-1.2, -2.0, b)
    front = h + 0.14 * helix + 0.05 * lobe
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

    # assemble the parts (triangle labels kept: the texture painter's masks use them)
    Ps, Ts, isl = [], [], []
    base = 0
    for k, name in enumerate(PARTS):
        P, T = parts[name]
        Ps.append(P)
        Ts.append(T + base)
        isl.append(np.full(len(T), k, np.int8))
        base += len(P)
    P = np.concatenate(Ps)
    T = np.concatenate(Ts)
    island = np.concatenate(isl)
    # normals: smooth across part boundaries (vertices at the same position share a normal), but
    # the flat bottom cut keeps its own (sharp edge)
    key = np.round(P, 6)
    bottom = np.zeros(len(P), bool)
    b0 = sum(len(parts[n][0]) for n in PARTS[:2])
    bottom[b0 : b0 + len(parts["bottom_cap"][0])] = True
    key = np.concatenate([key, bottom[:, None].astype(float)], 1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    N = _vertex_normals(P, T, group.ravel())
    # UV layout: xatlas charts of the welded surface, packed with ATLAS_PADDING_TEXELS gutters at
    # ATLAS_RESOLUTION (dermis.geometry.atlas); vertices split along the chart seams
    vm, T, UV = atlas_on_welded_surface(P, T, ATLAS_RESOLUTION, ATLAS_PADDING_TEXELS)
    P, N = P[vm], N[vm]
    T = T.astype(np.int64)
    UV = UV.astype(np.float64)

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
        "upper_lip": [0, shape.STOMION_Y + 0.45, 9.5],
        "lower_lip": [0, shape.STOMION_Y - 0.5, 9.5],
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
    return dict(P=P, N=N, UV=UV, T=T, island=island, landmarks=lm, shape=shape, ear=ear)


# ----------------------------------------------------------------------------------------------
# texture space
# ----------------------------------------------------------------------------------------------


def _value_noise3(P, cell, rng, smooth=1.0):
    """Smooth 3-D value noise (zero mean, ~unit std) at points P (n, 3), feature size ~cell."""
    lo = P.min(0) - 2 * cell
    dims = np.ceil((P.max(0) + 2 * cell - lo) / cell).astype(int) + 1
    lat = rng.standard_normal(tuple(dims)).astype(np.float32)
    if smooth > 0:
        lat = ndimage.gaussian_filter(lat, smooth, mode="wrap")
    lat /= lat.std() + 1e-12
    coords = ((P - lo) / cell).T.astype(np.float32)
    return ndimage.map_coordinates(lat, coords, order=1, mode="nearest").astype(np.float32)


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


def _lip_mask(x, y, z, shape):
    """Vermilion of the lips (soft edges ~0.5 mm), from the front-projected lip outline."""
    ys = shape.STOMION_Y
    xu = np.abs(x) / 2.05
    xl = np.abs(x) / 1.92
    # upper border with a cupid's bow; lower border a flatter arc
    yu = ys + 0.06 + 0.86 * np.clip(1 - xu**2.2, 0, 1) ** 0.55 - 0.09 * np.exp(-((x / 0.2) ** 2)) + 0.05 * np.exp(-(((np.abs(x) - 0.5) / 0.3) ** 2))
    yl = ys - 0.95 * np.clip(1 - xl**2, 0, 1) ** 0.6
    e = 0.05
    m = _sstep(-e, e, yu - y) * _sstep(-e, e, y - yl) * _sstep(7.4, 7.9, z) * _sstep(2.15, 1.95, np.abs(x))
    return m


def _eye_fields(x, y, z, shape):
    """(lid mask, lash line intensity, lid closure groove distance) for both eyes."""
    ex, ey, ez = shape.EYE
    ax = np.abs(x)
    d = np.sqrt((ax - ex) ** 2 + (y - ey) ** 2 + (z - ez) ** 2)
    lid = _sstep(shape.EYE_R + 0.35, shape.EYE_R + 0.08, d) * _sstep(ez + 0.2, ez + 0.7, z)
    t = (ax - ex) / 1.2
    yc = ey - 0.2 + 0.3 * t**2 - 0.06 * t  # closed-lid line: a gentle arc, corners higher
    along = _sstep(1.08, 0.95, np.abs(t))
    dist = y - yc
    return lid, along, dist


def _brow_mask(x, y, z):
    ax = np.abs(x)
    t = (ax - 1.05) / 3.9
    yb = 3.2 + 0.33 * np.sin(np.pi * np.clip(t * 0.85, 0, 1)) - 0.05 * t
    wb = 0.42 * (1 - 0.55 * np.clip(t, 0, 1))
    m = _sstep(1.0, 0.45, np.abs(y - yb) / wb) * _sstep(-0.08, 0.15, t) * _sstep(1.05, 0.8, t) * _sstep(5.5, 6.5, z)
    return m


def _textures(geo, size, seed):
    P, N, UV, T, isl, shape = geo["P"], geo["N"], geo["UV"], geo["T"], geo["island"], geo["shape"]
    H = W = int(size)
    rng = np.random.default_rng(seed)
    tri, bary = rasterize_uv(UV, T, W, H)
    cov = tri >= 0
    ti = tri[cov]
    b = bary[cov]
    P32, N32 = P.astype(np.float32), N.astype(np.float32)
    pos = np.einsum("nk,nkj->nj", b, P32[T[ti]])
    nrm = np.einsum("nk,nkj->nj", b, N32[T[ti]])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    island = isl[ti]
    n_all = len(pos)
    y = pos[:, 1]

    # per-triangle Jacobian (millimetres per UV unit) and texel size
    Pm = P * MM_PER_UNIT
    e1, e2 = Pm[T[:, 1]] - Pm[T[:, 0]], Pm[T[:, 2]] - Pm[T[:, 0]]
    d1, d2 = UV[T[:, 1]] - UV[T[:, 0]], UV[T[:, 2]] - UV[T[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    Pu = ((e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) / det[:, None]).astype(np.float32)
    Pv = ((e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) / det[:, None]).astype(np.float32)
    tmm_tri = np.sqrt(0.5 * np.linalg.norm(np.cross(e1, e2), axis=1) / (0.5 * np.abs(det) * W * H))
    texel_mm = float(np.median(tmm_tri[isl != PARTS.index("bottom_cap")]))

    def full(vals, fill=0.0):
        img = np.full((H, W), fill, np.float32)
        img[cov] = vals
        return img

    # the face features are only evaluated on the front of the head
    fi = np.nonzero((pos[:, 2] > 2.5) & (y > -12.0) & (y < 9.0) & (island == 0))[0]
    fp = pos[fi]
    x, fy, z = fp[:, 0], fp[:, 1], fp[:, 2]

    def face(vals):
        out = np.zeros(n_all, np.float32)
        out[fi] = vals
        return out

    ear = (island >= 3).astype(np.float32)
    bottom = (island == 2).astype(np.float32)
    scalp = np.clip(_sstep(5.0, 8.0, y) * (1 - _sstep(6.0, 8.5, pos[:, 2])) + (island == 1), 0, 1)
    neck = _sstep(-9.0, -11.5, y) * (1 - ear)
    front = _sstep(3.5, 6.5, z)
    lips_f = _lip_mask(x, fy, z, shape)
    lid_f, lid_along, lid_dist = _eye_fields(x, fy, z, shape)
    brow_f = _brow_mask(x, fy, z)
    lm = geo["landmarks"]
    nos_f = np.zeros(len(fi), np.float32)
    for prim in shape.nostrils:
        near = np.linalg.norm(fp - prim.c, axis=1) < 1.2
        nos_f[near] += _sstep(0.1, -0.04, prim(fp[near].astype(float)))
    nose_f = np.exp(-((x / 1.1) ** 2) - ((fy + 0.5) / 2.6) ** 2) * _sstep(8.0, 9.5, z)
    nose_f += np.exp(-np.sum((fp - lm["nose_tip"]) ** 2, axis=1) / 1.2**2)
    cheeks_f = np.exp(-(((np.abs(x) - 3.8) / 1.7) ** 2) - ((fy + 1.2) / 1.6) ** 2) * front
    chin_f = np.exp(-np.sum((fp - lm["chin"]) ** 2, axis=1) / 1.8**2)
    forehead_f = _sstep(3.7, 4.6, fy) * _sstep(7.8, 5.0, fy) * np.exp(-((x / 4.2) ** 4)) * front
    lips, lid, brow, nos = face(lips_f), face(lid_f), face(brow_f), face(nos_f)
    nose, cheeks, chin, forehead = face(nose_f), face(cheeks_f), face(chin_f), face(forehead_f)

    # ---------------------------------------------------------------- height field (mm)
    # pores: dimples on a jittered grid PORE_SPACING_MM apart
    sp = PORE_SPACING_MM / texel_mm
    pr, pc = _jittered_points(H, W, sp, rng)
    dens = np.clip(0.75 + 0.35 * nose + 0.35 * cheeks + 0.2 * chin - 0.35 * neck - 0.3 * scalp - 0.5 * ear
                   - lips - 0.8 * lid - 0.5 * brow, 0, 1.5) * (1 - bottom)
    dens_img = full(dens)
    amp = rng.uniform(0.5, 1.2, len(pr)) * dens_img[np.round(pr).astype(int), np.round(pc).astype(int)]
    sig = max(0.22 * sp, 0.6)
    depth = 0.06  # mm
    pores = ndimage.gaussian_filter(_splat(H, W, pr, pc, amp * depth * 2 * np.pi * sig * sig).astype(np.float32), sig)
    # micro-relief: band-limited noise, ~0.3-1 mm
    wn = rng.standard_normal((H, W), dtype=np.float32)
    s1, s2 = max(0.3 / texel_mm, 0.5), max(1.0 / texel_mm, 1.5)
    micro = ndimage.gaussian_filter(wn, s1) - ndimage.gaussian_filter(wn, s2)
    micro *= 0.008 / (micro.std() + 1e-12)
    # wrinkles and folds from 3-D positions (continuous across UV seams), on the face only
    # smooth noise fields are evaluated at the vertices and interpolated (cheaper than per texel)
    # the 3-D noise has its own random stream: its pattern does not depend on how many pores the
    # UV layout's texel size made room for
    rng3 = np.random.default_rng([seed, 3])
    vn = np.stack([_value_noise3(P, cell, rng3) for cell in (0.6, 2.5, 0.8, 1.6)], 1)
    n_line_all, n_big, n_mid, n_blotch = np.einsum("nk,nkc->cn", b, vn[T[ti]])
    n_line = n_line_all[fi]
    h3 = np.zeros(len(fi), np.float32)
    for k, yk in enumerate((4.7, 5.35, 6.0, 6.7)):
        yy = yk + 0.1 * (x / 3.0) ** 2 + 0.05 * n_line
        h3 -= 0.035 * np.exp(-(((fy - yy) / 0.045) ** 2)) * np.clip(0.7 + 0.5 * n_line, 0, 1.2) * _sstep(4.2, 2.0, np.abs(x) + 0.3 * k)
    h3 *= forehead_f
    # crow's feet
    dx = np.abs(x) - 4.3
    dy = fy - (shape.EYE[1] - 0.05)
    r = np.hypot(dx, dy)
    th = np.arctan2(dy, dx)
    cf = sum(np.exp(-(((th - a) * r / 0.03) ** 2)) for a in (-0.55, -0.22, 0.08, 0.38))
    h3 -= 0.04 * cf * _sstep(0.25, 0.5, r) * _sstep(1.5, 0.9, r) * (dx > 0) * front
    # closed-eye lid groove
    h3 -= 0.12 * np.exp(-((lid_dist / 0.035) ** 2)) * lid_along * lid_f
    # mouth line and the vertical lip lines
    ys = shape.STOMION_Y + 0.03 * (x / 2.0) ** 2
    mouth_f = np.exp(-(((fy - ys) / 0.04) ** 2)) * _sstep(2.15, 1.8, np.abs(x)) * _sstep(7.4, 7.9, z)
    h3 -= 0.15 * mouth_f
    ll = (0.5 + 0.5 * np.cos(2 * np.pi * x / 0.13 + 2.5 * n_line)) ** 6
    h3 -= 0.01 * lips_f * ll
    # labio-mental sulcus (the horizontal fold between the lower lip and the chin)
    h3 -= 0.3 * np.exp(-(((fy - (LABIOMENTAL_Y + 0.06 * x * x)) / 0.2) ** 2)) * _sstep(2.2, 1.4, np.abs(x)) * _sstep(7.0, 8.0, z)
    # naso-labial folds
    for sgn in (1, -1):
        cx = sgn * NASOLABIAL_X(fy)
        h3 -= 0.25 * np.exp(-(((x - cx) / 0.22) ** 2)) * _sstep(-2.0, -2.6, fy) * _sstep(-6.6, -5.6, fy) * front
    height = full(face(h3)) - pores + micro * full(1 - 0.7 * lips - 0.5 * bottom)
    # fill the gutters before differentiating
    inds = ndimage.distance_transform_edt(~cov, return_distances=False, return_indices=True)
    gut = ~cov.ravel()
    src = (inds[0] * W + inds[1]).ravel()[gut]  # nearest covered texel of each gutter texel
    height = height.ravel()
    height[gut] = height[src]
    height = height.reshape(H, W)
    g_row, g_col = np.gradient(height)
    hu = g_col[cov] * W  # dh/du (mm per UV unit)
    hv = -g_row[cov] * H  # dh/dv
    # tangent frame of the renderer: T = dP/du orthogonalised against N, B = w cross(N, T) with
    # w = +1 on counter-clockwise UV charts and -1 on mirrored ones (dermis.scene.tangents); the
    # surface gradient of h expressed in (T, B) is exact for any (even sheared) UV map
    pu, pv = Pu[ti], Pv[ti]
    tt = pu - nrm * np.einsum("ij,ij->i", pu, nrm)[:, None]
    tt /= np.linalg.norm(tt, axis=1, keepdims=True)
    bb = np.sign(det[ti]).astype(np.float32)[:, None] * np.cross(nrm, tt)
    gT = hu / np.einsum("ij,ij->i", pu, tt)
    gB = (hv - gT * np.einsum("ij,ij->i", pv, tt)) / np.einsum("ij,ij->i", pv, bb)
    nts = np.stack([-gT, -gB, np.ones_like(gT)], 1)
    nts /= np.linalg.norm(nts, axis=1, keepdims=True)

    # ---------------------------------------------------------------- albedo (linear RGB)
    melanin = 0.09 * n_big + 0.045 * n_mid
    col = np.exp(-melanin[:, None] * np.array([0.9, 1.25, 1.6], np.float32))
    redness = (0.45 * cheeks + 0.4 * nose + 0.15 * chin + 0.2 * ear + 0.12 * lid
               + 0.22 * np.maximum(n_blotch - 0.3, 0) - 0.12 * neck)
    col *= 1 + redness[:, None] * np.array([0.04, -0.33, -0.25], np.float32)
    col *= 1 + neck[:, None] * np.array([0.0, 0.03, 0.04], np.float32)
    # freckles: 0.5-1 mm brown spots, mostly on nose and cheeks
    fsp = 2.6 / texel_mm
    fr, fc = _jittered_points(H, W, fsp, rng)
    fmask = full(np.clip(0.9 * nose + 1.0 * cheeks + 0.25 * forehead + 0.15, 0, 1.2) * (1 - lips) * (1 - bottom))
    famp = (rng.random(len(fr)) < 0.55) * rng.uniform(0.3, 1.0, len(fr)) * fmask[np.round(fr).astype(int), np.round(fc).astype(int)]
    fs = max(0.45 / texel_mm, 0.7)
    freck = np.clip(ndimage.gaussian_filter(_splat(H, W, fr, fc, famp * 2 * np.pi * fs * fs).astype(np.float32), fs)[cov], 0, 1)
    col *= 1 - 0.3 * freck[:, None] * np.array([0.55, 0.8, 1.0], np.float32)
    # calibrate plain skin to the target mean
    target = np.array([0.45, 0.25, 0.17])
    plain = (lips < 0.05) & (brow < 0.05) & (lid < 0.05) & (nos < 0.05) & (bottom == 0)
    col *= (target / col[plain].mean(0)).astype(np.float32)
    # eyelids, lash line, brows, lips, nostrils, mouth line (on the face texels)
    cf_ = col[fi]
    cf_ *= 1 - lid_f[:, None] * np.array([0.05, 0.12, 0.1], np.float32)
    nm_f = n_mid[fi]
    strokes = (0.5 + 0.5 * np.cos(2 * np.pi * x / 0.06 + 3 * nm_f)) ** 4
    lid_wide = _sstep(shape.EYE_R + 0.45, shape.EYE_R + 0.2,
                      np.sqrt((np.abs(x) - shape.EYE[0]) ** 2 + (fy - shape.EYE[1]) ** 2 + (z - shape.EYE[2]) ** 2))
    lash = lid_wide * lid_along * _sstep(shape.EYE[2] + 0.2, shape.EYE[2] + 0.6, z) * (
        np.exp(-((lid_dist / 0.045) ** 2)) + 0.8 * strokes * _sstep(0.0, -0.02, lid_dist) * _sstep(-0.2, -0.05, lid_dist))
    lash = np.clip(lash, 0, 1)
    hair = np.zeros(len(fi), np.float32)
    ib = brow_f > 0
    if np.any(ib):
        hair[ib] = np.clip(0.6 + 0.4 * _value_noise3(fp[ib] * [0.25, 1.0, 1.0], 0.05, rng3, smooth=0.7), 0, 1)
    brow_a = np.clip(0.8 * brow_f * hair, 0, 1)[:, None]
    lip_col = np.array([0.45, 0.12, 0.10], np.float32) * (1 + 0.07 * nm_f[:, None]) * (1 - 0.06 * ll[:, None])
    lf = lips_f[:, None]
    cf_ = cf_ * (1 - lf) + lip_col * lf
    cf_ = cf_ * (1 - brow_a) + np.array([0.10, 0.06, 0.045], np.float32) * brow_a
    cf_ = cf_ * (1 - lash[:, None]) + np.array([0.03, 0.022, 0.018], np.float32) * lash[:, None]
    cf_ *= 1 - 0.8 * np.clip(nos_f, 0, 1)[:, None]
    cf_ *= 1 - 0.45 * mouth_f[:, None] * np.array([0.6, 1.0, 1.0], np.float32)
    col[fi] = cf_
    col = np.clip(col, 0.0, 1.0)

    # ---------------------------------------------------------------- specular intensity
    pnorm = np.clip(pores[cov] / (depth * 0.6), 0, 1)
    spec = (0.32 + 0.25 * forehead + 0.3 * nose + 0.15 * chin + 0.08 * scalp + 0.35 * lips - 0.22 * brow
            - 0.1 * cheeks - 0.08 * neck - 0.12 * pnorm + 0.04 * n_mid - 0.15 * bottom)
    spec = np.clip(spec, 0.0, 1.0)

    def finish(vals):
        img = np.zeros((H * W,) + vals.shape[1:], np.float32)
        img[cov.ravel()] = vals
        img[gut] = img[src]  # dilate: gutters take the nearest island texel
        return img.reshape((H, W) + vals.shape[1:])

    return finish(col), finish(nts * 0.5 + 0.5), finish(spec), texel_mm


def _readonly(a):
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=4)
def build_default_head(texture_size: int = 1024, seed: int = 7) -> ProceduralHead:
    """The built-in default scene's head-and-neck bust (see the module docstring).

    Deterministic for given arguments and cached: the returned arrays are read-only."""
    if int(texture_size) < 64:
        raise ValueError("texture_size must be at least 64")
    geo = _geometry()
    albedo, normal_map, specular, texel_mm = _textures(geo, int(texture_size), int(seed))
    return ProceduralHead(
        positions=_readonly(geo["P"].astype(np.float32)),
        normals=_readonly(geo["N"].astype(np.float32)),
        uvs=_readonly(geo["UV"].astype(np.float32)),
        indices=_readonly(geo["T"].astype(np.uint32)),
        albedo=_readonly(albedo),
        normal_map=_readonly(normal_map),
        specular=_readonly(specular),
        mm_per_unit=MM_PER_UNIT,
        pore_spacing_mm=PORE_SPACING_MM,
        landmarks={k: _readonly(v) for k, v in geo["landmarks"].items()},
        islands=_readonly(geo["island"]),
        texel_mm=texel_mm,
    )
