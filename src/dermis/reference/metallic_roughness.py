"""Non-skin surfaces in the offline reference: glTF 2.0's metallic-roughness BRDF evaluated at
the visible point (no scattering), the numpy twin of shaders/metallic_roughness/surface.frag and
shaders/common/metallic_roughness.glsl (glTF 2.0 spec, Appendix B). Shadows are ray cast against
everything (skin and surfaces; both faces occlude); the environment's diffuse is the same SH
irradiance, its specular the Monte Carlo integral of the GGX lobe against the HDR
(:func:`environment_specular_ggx_mc`; the real-time path prefilters it), both scaled by the
material's occlusion only (surfaces get no baked ambient occlusion in the real-time
techniques either). alphaMode MASK surfaces are refused by the reference (its rays do not test
alpha).
"""

from __future__ import annotations

import numpy as np

from dermis.environment import irradiance_sh_eval
from dermis.reference.sampling import bilinear, wrapped_uv

MIN_ROUGHNESS = 0.03
"""As surface.frag: the smallest perceptual roughness shaded."""


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def brdf_terms(N, L, V, base, metallic, roughness):
    """glTF 2.0 B.3.2-B.3.5 per row: (diffuse, specular) BRDF values (1/sr), 0 where N.L or N.V <= 0.
    D: Trowbridge-Reitz/GGX (alpha = roughness^2); V: height-correlated Smith (Heitz 2014, eq. 99);
    F: Schlick with F0 = mix(0.04, base, metallic); diffuse (1 - F)(1 - metallic) base / pi."""
    H = _unit(L + V)
    ndl, ndv = np.sum(N * L, -1), np.sum(N * V, -1)
    ok = (ndl > 0) & (ndv > 0)
    ndl, ndv = np.maximum(ndl, 1e-12)[:, None], np.maximum(ndv, 1e-12)[:, None]
    ndh, vdh = np.sum(N * H, -1)[:, None], np.sum(V * H, -1)[:, None]
    a2 = (roughness ** 4)[:, None]
    D = np.where(ndh > 0, a2 / (np.pi * (ndh * ndh * (a2 - 1) + 1) ** 2), 0.0)
    vis = 0.5 / (ndl * np.sqrt(ndv * ndv * (1 - a2) + a2) + ndv * np.sqrt(ndl * ndl * (1 - a2) + a2))
    m = metallic[:, None]
    f0 = 0.04 * (1 - m) + base * m
    F = f0 + (1 - f0) * (1 - np.clip(np.abs(vdh), 0, 1)) ** 5
    diffuse = (1 - F) * (1 - m) * base / np.pi
    return np.where(ok[:, None], diffuse, 0.0), np.where(ok[:, None], F * D * vis, 0.0)


def environment_brdf(f0, ndv, roughness):
    """F0 A + B of common/metallic_roughness.glsl mr_environment_brdf (Karis 2014, EnvBRDFApprox)."""
    c0, c1 = np.array([-1.0, -0.0275, -0.572, 0.022]), np.array([1.0, 0.0425, 1.04, -0.04])
    r = roughness[:, None] * c0 + c1
    a004 = np.minimum(r[:, 0] * r[:, 0], np.exp2(-9.28 * ndv)) * r[:, 0] + r[:, 1]
    return f0 * (-1.04 * a004 + r[:, 2])[:, None] + (1.04 * a004 + r[:, 3])[:, None]


def environment_specular_ggx_mc(env_image, N, V, f0, roughness, samples: int = 64, seed: int = 1207):
    """integral L(l) f_spec(l, V) (N.l) dl over the hemisphere: the glTF specular BRDF (brdf_terms:
    GGX D, height-correlated Smith V, Schlick F) against the equirect ``env_image`` (bilinear,
    dermis.environment's orientation), per row. Monte Carlo with h drawn from GGX's normal
    distribution (Walter et al. 2007, eqs. 35-36: tan^2 theta_h = alpha^2 xi1 / (1 - xi1),
    phi = 2 pi xi2), l = reflect(-V, h), pdf(l) = D(h) (N.h) / (4 (V.h)), so the weight
    f (N.l) / pdf = 4 F Vis (N.l) (V.h) / (N.h). ``samples`` jittered strata per point (a square
    number), deterministic for a seed. Returns (n, 3)."""
    from dermis.reference.shading import sampled_reflections

    a2_all = np.asarray(roughness, np.float64) ** 4
    # GGX cos(theta_h) from xi1 (Walter et al. 2007, eq. 35)
    lobe = lambda xi, c0, c1: np.sqrt((1.0 - xi) / (1.0 + (a2_all[c0:c1, None] - 1.0) * xi))
    out = np.zeros((len(N), 3))
    for c0, c1, cos_h, vh, nl, L in sampled_reflections(env_image, N, V, lobe, samples, seed):
        a2 = a2_all[c0:c1, None]
        nv = np.maximum(np.sum(N[c0:c1] * V[c0:c1], -1), 1e-12)[:, None]
        ok = (vh > 0.0) & (nl > 0.0)
        nlc = np.maximum(nl, 1e-12)
        vis = 0.5 / (nlc * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nlc * nlc * (1 - a2) + a2))
        w = np.where(ok, 4.0 * vis * nlc * vh / np.maximum(cos_h, 1e-12), 0.0)
        F = f0[c0:c1, None, :] + (1.0 - f0[c0:c1, None, :]) * ((1.0 - np.clip(vh, 0, 1)) ** 5)[..., None]
        out[c0:c1] = np.mean(w[..., None] * F * L, axis=1)
    return out


class SurfaceProps:
    """The scene's non-skin surfaces in millimetres, their triangles numbered after the skin's
    (``first``) in the shared ray caster."""

    def __init__(self, scene, first: int):
        mm = float(scene.mm_per_unit)
        self.first = int(first)
        self.surfaces = list(scene.surfaces)
        P, N, UV, UV1, T, I, owner = [], [], [], [], [], [], []
        base = 0
        for k, s in enumerate(self.surfaces):
            m = s.mesh
            P.append(np.asarray(m.positions, np.float64) * mm)
            N.append(np.asarray(m.normals, np.float64))
            UV.append(np.asarray(m.uvs, np.float64))
            UV1.append(np.zeros((len(m.positions), 2)) if m.uvs1 is None else np.asarray(m.uvs1, np.float64))
            T.append(np.asarray(m.tangents, np.float64))
            I.append(np.asarray(m.indices, np.int64) + base)
            owner.append(np.full(len(m.indices), k))
            base += len(m.positions)
        self.positions_mm, self.normals, self.uvs, self.uvs1, self.tangents = (np.concatenate(a) for a in (P, N, UV, UV1, T))
        self.indices, self.owner = np.concatenate(I), np.concatenate(owner)
        p = self.positions_mm
        cross = np.cross(p[self.indices[:, 1]] - p[self.indices[:, 0]], p[self.indices[:, 2]] - p[self.indices[:, 0]])
        self.face_normals = _unit(cross)

    # ------------------------------------------------------------------ maps
    @staticmethod
    def _sample(tex, uv0, uv1, default):
        """A map (Texture) at the points, through its UV set and transform (map_uv), or ``default``."""
        if tex is None:
            return np.broadcast_to(np.asarray(default, np.float64), (len(uv0), len(default)))
        uv = uv1 if tex.texcoord == 1 else uv0
        T = tex.uv_matrix().astype(np.float64)
        uv = uv @ T[:2, :2].T + T[:2, 2]
        img = np.ascontiguousarray(tex.data, np.float32)
        return bilinear(img, *wrapped_uv(uv, tex))

    def shade(self, tri, bary, eye_mm, rig, bvh, env_sh, env_image=None):
        """(diffuse, specular) radiance (n, 3) at camera hits on triangles ``tri`` (ids in the
        shared ray caster) with barycentrics (n, 2) of corners 1, 2; emission counts as diffuse."""
        local = np.asarray(tri, np.int64) - self.first
        b = np.c_[1.0 - bary.sum(1), bary]
        corners = self.indices[local]

        def lerp(a):
            return np.einsum("nk,nkc->nc", b, a[corners])

        P = lerp(self.positions_mm)
        V = _unit(eye_mm[None, :] - P)
        Ng = _unit(lerp(self.normals))
        fn = self.face_normals[local]
        # a back face (as the camera sees the winding) is lit with its normal reversed (glTF 3.9.6);
        # single-sided back faces are culled on the GPU, shaded here like double-sided ones
        back = np.sum(fn * V, 1) < 0
        Ng = np.where(back[:, None], -Ng, Ng)
        fn = np.where(back[:, None], -fn, fn)
        uv0, uv1, Tg = lerp(self.uvs), lerp(self.uvs1), lerp(self.tangents)
        diffuse, specular = np.zeros((len(P), 3)), np.zeros((len(P), 3))
        owner = self.owner[local]
        for k, s in enumerate(self.surfaces):
            sel = np.nonzero(owner == k)[0]
            if len(sel) == 0:
                continue
            mat = s.material
            a, a1 = uv0[sel], uv1[sel]
            base = np.asarray(mat.base_color, np.float64)[:3] * self._sample(mat.base_color_map, a, a1, (1, 1, 1, 1))[:, :3]
            mr = self._sample(mat.metallic_roughness_map, a, a1, (1, 1, 1))
            metallic = np.clip(mat.metallic * mr[:, 2], 0, 1)
            rough = np.maximum(np.clip(mat.roughness * mr[:, 1], 0, 1), MIN_ROUGHNESS)
            # perturb_normal of common/surface.glsl with normalTexture.scale (MikkTSpace frame)
            n = Ng[sel]
            m = self._sample(mat.normal_map, a, a1, (0.5, 0.5, 1.0)) * 2.0 - 1.0
            m[:, :2] *= float(mat.normal_scale)
            t = _unit(Tg[sel, :3] - n * np.sum(n * Tg[sel, :3], 1, keepdims=True))
            bt = Tg[sel, 3:4] * np.cross(n, t)
            N = _unit(t * m[:, :1] + bt * m[:, 1:2] + n * m[:, 2:3])
            v = V[sel]
            for i in range(len(rig.lights)):
                L, E, dist = rig.incident(i, P[sel])
                ndl = np.sum(N * L, 1)
                lit = (ndl > 0) & (np.sum(n * L, 1) > -0.05)
                vis = lit.astype(np.float64)
                idx = np.nonzero(lit)[0]
                if rig.lights[i]["cast_shadows"] and len(idx):
                    o = P[sel][idx] + fn[sel][idx] * rig.epsilon_mm
                    occ = bvh.occluded(o, L[idx], 0.0, dist[idx] - rig.epsilon_mm, skip=np.asarray(tri)[sel][idx])
                    vis[idx[occ]] = 0.0
                fd, fs = brdf_terms(N, L, v, base, metallic, rough)
                w = (E * (vis * np.maximum(ndl, 0.0))[:, None])
                diffuse[sel] += w * fd
                specular[sel] += w * fs
            ao = 1.0 + mat.occlusion_strength * (self._sample(mat.occlusion_map, a, a1, (1.0,))[:, 0] - 1.0)
            ndv = np.clip(np.sum(N * v, 1), 0, 1)
            R = 2.0 * np.sum(N * v, 1, keepdims=True) * N - v
            c_diff = (1 - metallic)[:, None] * base
            f0 = 0.04 * (1 - metallic)[:, None] + base * metallic[:, None]
            diffuse[sel] += ao[:, None] * c_diff / np.pi * irradiance_sh_eval(env_sh, N)
            if env_image is None:  # a constant environment: E_sh(R) / pi is its radiance, exactly
                specular[sel] += ao[:, None] * irradiance_sh_eval(env_sh, R) / np.pi * environment_brdf(f0, ndv, rough)
            else:
                specular[sel] += ao[:, None] * environment_specular_ggx_mc(env_image, N, v, f0, rough)
            diffuse[sel] += np.asarray(mat.emissive, np.float64) * self._sample(mat.emissive_map, a, a1, (1, 1, 1))[:, :3]
        return diffuse, specular
