"""The head and neck as one implicit surface: smooth unions of ellipsoids and capsules minus smooth
subtractions (signed-distance-like values, centimetres), and ray casting against it by bracketed
bisection from the centre C it is star-shaped around."""

from __future__ import annotations

import numpy as np

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


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)
