"""The ears: thin closed shells (a ~2.6 mm flap with a rounded rim) whose front edge is buried in
the side of the head, so that they transmit light when back-lit."""

from __future__ import annotations

import numpy as np

from dermis.scene.procedural_head.implicit import _raycast, _smoothstep
from dermis.scene.procedural_head.meshing import _orient_outward

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
