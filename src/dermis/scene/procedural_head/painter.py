"""The procedural head's texture painter: albedo, tangent-space normal map and specular intensity,
painted per texel of the UV layout from 3-D positions (features continuous across UV seams) and
from texel-space pores and freckles."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from dermis.geometry.rasterize import rasterize_uv
from dermis.scene.procedural_head.implicit import _smoothstep
from dermis.scene.procedural_head.model import LABIOMENTAL_Y, MM_PER_UNIT, NASOLABIAL_X, PARTS, PORE_SPACING_MM

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




def _lip_mask(x, y, z, shape):
    """Vermilion of the lips (soft edges ~0.5 mm), from the front-projected lip outline."""
    ys = shape.STOMION_Y
    xu = np.abs(x) / 2.05
    xl = np.abs(x) / 1.92
    # upper border with a cupid's bow; lower border a flatter arc
    yu = ys + 0.06 + 0.86 * np.clip(1 - xu**2.2, 0, 1) ** 0.55 - 0.09 * np.exp(-((x / 0.2) ** 2)) + 0.05 * np.exp(-(((np.abs(x) - 0.5) / 0.3) ** 2))
    yl = ys - 0.95 * np.clip(1 - xl**2, 0, 1) ** 0.6
    e = 0.05
    m = _smoothstep(-e, e, yu - y) * _smoothstep(-e, e, y - yl) * _smoothstep(7.4, 7.9, z) * _smoothstep(2.15, 1.95, np.abs(x))
    return m


def _eye_fields(x, y, z, shape):
    """(lid mask, lash line intensity, lid closure groove distance) for both eyes."""
    ex, ey, ez = shape.EYE
    ax = np.abs(x)
    d = np.sqrt((ax - ex) ** 2 + (y - ey) ** 2 + (z - ez) ** 2)
    lid = _smoothstep(shape.EYE_R + 0.35, shape.EYE_R + 0.08, d) * _smoothstep(ez + 0.2, ez + 0.7, z)
    t = (ax - ex) / 1.2
    yc = ey - 0.2 + 0.3 * t**2 - 0.06 * t  # closed-lid line: a gentle arc, corners higher
    along = _smoothstep(1.08, 0.95, np.abs(t))
    dist = y - yc
    return lid, along, dist


def _brow_mask(x, y, z):
    ax = np.abs(x)
    t = (ax - 1.05) / 3.9
    yb = 3.2 + 0.33 * np.sin(np.pi * np.clip(t * 0.85, 0, 1)) - 0.05 * t
    wb = 0.42 * (1 - 0.55 * np.clip(t, 0, 1))
    m = _smoothstep(1.0, 0.45, np.abs(y - yb) / wb) * _smoothstep(-0.08, 0.15, t) * _smoothstep(1.05, 0.8, t) * _smoothstep(5.5, 6.5, z)
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
    scalp = np.clip(_smoothstep(5.0, 8.0, y) * (1 - _smoothstep(6.0, 8.5, pos[:, 2])) + (island == 1), 0, 1)
    neck = _smoothstep(-9.0, -11.5, y) * (1 - ear)
    front = _smoothstep(3.5, 6.5, z)
    lips_f = _lip_mask(x, fy, z, shape)
    lid_f, lid_along, lid_dist = _eye_fields(x, fy, z, shape)
    brow_f = _brow_mask(x, fy, z)
    lm = geo["landmarks"]
    nos_f = np.zeros(len(fi), np.float32)
    for prim in shape.nostrils:
        near = np.linalg.norm(fp - prim.c, axis=1) < 1.2
        nos_f[near] += _smoothstep(0.1, -0.04, prim(fp[near].astype(float)))
    nose_f = np.exp(-((x / 1.1) ** 2) - ((fy + 0.5) / 2.6) ** 2) * _smoothstep(8.0, 9.5, z)
    nose_f += np.exp(-np.sum((fp - lm["nose_tip"]) ** 2, axis=1) / 1.2**2)
    cheeks_f = np.exp(-(((np.abs(x) - 3.8) / 1.7) ** 2) - ((fy + 1.2) / 1.6) ** 2) * front
    chin_f = np.exp(-np.sum((fp - lm["chin"]) ** 2, axis=1) / 1.8**2)
    forehead_f = _smoothstep(3.7, 4.6, fy) * _smoothstep(7.8, 5.0, fy) * np.exp(-((x / 4.2) ** 4)) * front
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
        h3 -= 0.035 * np.exp(-(((fy - yy) / 0.045) ** 2)) * np.clip(0.7 + 0.5 * n_line, 0, 1.2) * _smoothstep(4.2, 2.0, np.abs(x) + 0.3 * k)
    h3 *= forehead_f
    # crow's feet
    dx = np.abs(x) - 4.3
    dy = fy - (shape.EYE[1] - 0.05)
    r = np.hypot(dx, dy)
    th = np.arctan2(dy, dx)
    cf = sum(np.exp(-(((th - a) * r / 0.03) ** 2)) for a in (-0.55, -0.22, 0.08, 0.38))
    h3 -= 0.04 * cf * _smoothstep(0.25, 0.5, r) * _smoothstep(1.5, 0.9, r) * (dx > 0) * front
    # closed-eye lid groove
    h3 -= 0.12 * np.exp(-((lid_dist / 0.035) ** 2)) * lid_along * lid_f
    # mouth line and the vertical lip lines
    ys = shape.STOMION_Y + 0.03 * (x / 2.0) ** 2
    mouth_f = np.exp(-(((fy - ys) / 0.04) ** 2)) * _smoothstep(2.15, 1.8, np.abs(x)) * _smoothstep(7.4, 7.9, z)
    h3 -= 0.15 * mouth_f
    ll = (0.5 + 0.5 * np.cos(2 * np.pi * x / 0.13 + 2.5 * n_line)) ** 6
    h3 -= 0.01 * lips_f * ll
    # labio-mental sulcus (the horizontal fold between the lower lip and the chin)
    h3 -= 0.3 * np.exp(-(((fy - (LABIOMENTAL_Y + 0.06 * x * x)) / 0.2) ** 2)) * _smoothstep(2.2, 1.4, np.abs(x)) * _smoothstep(7.0, 8.0, z)
    # naso-labial folds
    for sgn in (1, -1):
        cx = sgn * NASOLABIAL_X(fy)
        h3 -= 0.25 * np.exp(-(((x - cx) / 0.22) ** 2)) * _smoothstep(-2.0, -2.6, fy) * _smoothstep(-6.6, -5.6, fy) * front
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
    lid_wide = _smoothstep(shape.EYE_R + 0.45, shape.EYE_R + 0.2,
                      np.sqrt((np.abs(x) - shape.EYE[0]) ** 2 + (fy - shape.EYE[1]) ** 2 + (z - shape.EYE[2]) ** 2))
    lash = lid_wide * lid_along * _smoothstep(shape.EYE[2] + 0.2, shape.EYE[2] + 0.6, z) * (
        np.exp(-((lid_dist / 0.045) ** 2)) + 0.8 * strokes * _smoothstep(0.0, -0.02, lid_dist) * _smoothstep(-0.2, -0.05, lid_dist))
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
