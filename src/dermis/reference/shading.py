"""Lighting for the offline reference: the real-time shaders' formulas with exact ray-cast shadows.

Numpy twins of common/lights.glsl (light_incident), tsd/irradiance.frag (the irradiance that
scatters) and the specular of tsd/final.frag. The one intended difference: visibility is a
ray cast against the mesh through a BVH (hard, exact shadows, both faces occlude) where the
real-time techniques look up PCF-filtered shadow maps; the specular uses the same hard shadow
(the real-time "sharp" lookup approximates it). A point whose interpolated normal faces away
from a light (Ng . L <= 0) is in its own shadow, as the real-time shadow maps make it.

Environment light: the diffuse is the same spherical-harmonic irradiance the real-time techniques
use (common/environment.glsl), occluded the same way (dermis.geometry.visibility: r E_sh(N), r the
visible fraction of the irradiance), but with A and r ray cast at every sample point (AMBIENT_RAYS
cosine-weighted rays from the point, no distance limit) instead of baked per vertex and
interpolated: validate measures what the per-vertex bake loses. [environment] occlusion = false
turns it off in both. The environment's SPECULAR is not the real-time split-sum approximation
(a prefiltered map times the lobe's albedo, dermis.prefiltered_environment) but the integral of
the KSK BRDF against the HDR itself, by importance-sampled Monte Carlo with a fixed seed
(:func:`environment_specular_mc`), times the same specular occlusion (the L2 spherical harmonics of
the blocked directions, specular_occlusion_sh) projected from the point's own ambient rays: validate
measures the prefilter's error. A light's diffuse takes the normal map's shadowing by the smooth
surface as the shaders do (:func:`bump_shadowing`, common/shadow.glsl). For a constant environment the
integral is the constant times the specular albedo (the rho_dt table), as in real time.
"""

from __future__ import annotations

import numpy as np

from dermis.camera import normalize
from dermis.environment import environment_is_black
from dermis.geometry.visibility import (OFFSET_REL, blocked_sh_of_rays, environment_radiance, occluded_fraction,
                                        occluded_irradiance, specular_occlusion_sh)
from dermis.specular import ksk_specular
from dermis.techniques.shared import INV_PI, MAX_LIGHTS
SHADOW_EPSILON_REL = 1e-6
"""Shadow-ray origin offset along the face normal, relative to the mesh's bounding diagonal."""
AMBIENT_RAYS = 32
"""Cosine-weighted ambient-occlusion rays per sample point (standard error <= 0.5/sqrt(32) = 0.09 per
point; the scattering integral and the 4 sub-pixel samples average it further)."""
ENV_SPECULAR_SAMPLES = 64
"""Beckmann-importance-sampled directions per point for the environment's specular (8 x 8 jittered
strata); each pixel averages 4 sub-pixel points."""
ENV_SPECULAR_SEED = 1207
"""Seed of the environment specular's Monte Carlo (with the batch index: deterministic)."""
ENV_SPECULAR_CHUNK = 8_000
"""Points per environment-specular batch (bounds its arrays to about 40 MB)."""
AMBIENT_CHUNK = 20_000
"""Points per ambient-occlusion batch (bounds the ray arrays' memory to about 50 MB)."""


def bump_shadowing(ns, n, L):
    """common/shadow.glsl's bump_shadowing, per row: the normal map's tilted facet (mapped normal n on
    the smooth, interpolated normal ns) shadowed by the smooth surface (Conty Estevez, Lecocq & Stein
    2019, Ray Tracing Gems ch. 12): Smith's G1 of a GGX microsurface about ns with alpha^2 =
    tan^2(theta_d) / 8 (at most 1) at the light's angle to ns; 0 below ns's horizon, 1 where n = ns.
    Unitless (n, ) factor on a light's diffuse N.L."""
    cos_i = np.sum(ns * L, axis=1)
    cos_d = np.minimum(np.sum(ns * n, axis=1), 1.0)
    ci = np.clip(cos_i, 1e-6, 1.0)
    cd = np.maximum(cos_d, 1e-6)
    alpha2 = np.clip(0.125 * (1.0 / (cd * cd) - 1.0), 0.0, 1.0)
    tan2_i = 1.0 / (ci * ci) - 1.0
    g = 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * tan2_i))
    g = np.where((cos_d >= 1.0) | (cos_i >= 1.0), 1.0, g)
    return np.where(cos_i <= 1e-6, 0.0, g)


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


class LightRig:
    """The scene's lights (at most 8, as the real-time techniques) in millimetres."""

    MAX_LIGHTS = MAX_LIGHTS

    def __init__(self, scene, surface, bvh, ambient_bvh=None):
        self.surface = surface
        self.bvh = bvh  # shadow rays: everything that occludes (skin and non-skin surfaces)
        self.ambient_bvh = bvh if ambient_bvh is None else ambient_bvh  # ambient occlusion rays
        mm = float(scene.mm_per_unit)
        self.lights = []
        for L in scene.lights[: self.MAX_LIGHTS]:
            d = normalize(L.direction)
            outer = np.cos(np.radians(L.spot_angle_deg))
            inner = max(np.cos(np.radians(L.spot_angle_deg * (1 - L.spot_blend))), outer + 1e-4)
            self.lights.append({"kind": L.kind, "direction": d, "position_mm": np.asarray(L.position, np.float64) * mm,
                                "radiance": np.asarray(L.radiance_rgb(), np.float64), "cast_shadows": bool(L.cast_shadows),
                                "spot": (outer, inner)})
        lo, hi = scene.bounds()
        self.epsilon_mm = SHADOW_EPSILON_REL * float(np.linalg.norm((hi - lo) * mm)) + 1e-9
        self.ambient_offset_mm = OFFSET_REL * float(np.linalg.norm((hi - lo) * mm))
        env = scene.environment
        # a black environment has no light to occlude: no ambient rays are cast (the same image, bit for
        # bit; on a black-lit plane the rays were 80 % of the render's time)
        self.occlusion = bool(env.occlusion) and not environment_is_black(env)
        self.env_radiance = environment_radiance(env) if (self.occlusion and env.image is not None) else None
        self._ambient_batches = 0  # seeds successive ambient-occlusion batches differently, deterministically

    def ambient_visibility(self, attrs, blocked_sh: bool = True):
        """(A (n,), the visible fraction r (n, 3) of the SH irradiance) at the points ``attrs``:
        cosine-weighted rays about the interpolated normal from the shadow-ray origin
        (RayCaster.ambient_rays), the light they block integrated against the environment image
        (dermis.geometry.visibility.occluded_fraction), or (1, 1) with environment occlusion off.
        Cached in ``attrs``, with the L2 SH of the directions the rays found blocked (``attrs["blocked_sh"]``,
        dermis.geometry.visibility.blocked_sh_of_rays; 0 when off): the specular occlusion's, projected only
        with ``blocked_sh`` (the scattering's surface cells never read it: None there)."""
        if "ambient_occlusion" in attrs and blocked_sh and attrs["blocked_sh"] is None:
            raise ValueError("ambient_visibility: these points' rays were cast without their blocked SH")
        if "ambient_occlusion" not in attrs:
            ng = attrs["normal_geo"]
            blocked = np.zeros((len(ng), 9)) if blocked_sh else None
            if not self.occlusion:
                ao, frac = np.ones(len(ng)), np.ones((len(ng), 3))
            else:
                o = self.surface.shadow_origin(attrs)
                ao, frac = np.empty(len(ng)), np.empty((len(ng), 3))
                for c0 in range(0, len(ng), AMBIENT_CHUNK):
                    c1 = min(len(ng), c0 + AMBIENT_CHUNK)
                    self._ambient_batches += 1
                    ao[c0:c1], _, dirs, occ = self.ambient_bvh.ambient_rays(o[c0:c1], ng[c0:c1], AMBIENT_RAYS,
                                                                            offset=self.ambient_offset_mm,
                                                                            seed=self._ambient_batches)
                    n_unit = ng[c0:c1] / np.maximum(np.linalg.norm(ng[c0:c1], axis=1, keepdims=True), 1e-300)
                    if blocked is not None:
                        blocked[c0:c1] = blocked_sh_of_rays(n_unit, dirs, occ)
                    if self.env_radiance is None:  # a constant environment: r = A exactly
                        frac[c0:c1] = ao[c0:c1, None]
                    else:
                        n = ng[c0:c1] / np.maximum(np.linalg.norm(ng[c0:c1], axis=1, keepdims=True), 1e-300)
                        frac[c0:c1] = occluded_fraction(self.surface.env_sh, self.env_radiance, n, ao[c0:c1],
                                                        dirs, occ)
            attrs["ambient_occlusion"], attrs["visible_fraction"], attrs["blocked_sh"] = ao, frac, blocked
        return attrs["ambient_occlusion"], attrs["visible_fraction"]

    def incident(self, i, p_mm):
        """light_incident() of common/lights.glsl: (L (n, 3) unit, E (n, 3) irradiance at normal
        incidence, distance to the light in mm (inf for directional))."""
        lt = self.lights[i]
        n = len(p_mm)
        if lt["kind"] == "directional":
            L = np.broadcast_to(-lt["direction"], (n, 3)).copy()
            return L, np.broadcast_to(lt["radiance"], (n, 3)).copy(), np.full(n, np.inf)
        d = lt["position_mm"] - p_mm
        dist = np.linalg.norm(d, axis=1)
        L = d / np.maximum(dist, 1e-300)[:, None]
        dist_m = np.maximum(dist * 1e-3, 1e-4)
        E = lt["radiance"][None, :] / (dist_m * dist_m)[:, None]
        if lt["kind"] == "spot":
            c = np.sum(-L * lt["direction"], axis=1)
            E = E * _smoothstep(lt["spot"][0], lt["spot"][1], c)[:, None]
        return L, E, dist

    def visibility(self, i, attrs, L, dist, origins=None):
        """1 where light i reaches the point unoccluded (exact ray cast), else 0."""
        ng = attrs["normal_geo"]
        facing = np.sum(ng * L, axis=1) > 0.0
        vis = facing.astype(np.float64)
        if not self.lights[i]["cast_shadows"]:
            return vis
        idx = np.nonzero(facing)[0]
        if len(idx) == 0:
            return vis
        s = self.surface
        o = s.shadow_origin(attrs) if origins is None else origins
        fn = s.face_normals[attrs["tri"]]
        fn = np.where((np.sum(fn * ng, axis=1) < 0)[:, None], -fn, fn)
        o = o[idx] + fn[idx] * self.epsilon_mm
        tmax = dist[idx] - self.epsilon_mm
        occ = self.bvh.occluded(o, L[idx], 0.0, tmax, skip=attrs["tri"][idx])
        vis[idx[occ]] = 0.0
        return vis


def scattered_irradiance(surface, rig, attrs):
    """tsd/irradiance.frag with exact shadows: the light that enters the skin and scatters,
    sum_i E_i max(N.L, 0) G_bump V_i (1 - rho_s a(N.L, m)/pi) + r E_env(N) (1 - rho_s a(0.5, m)/pi),
    times albedo^mix. Returns (n, 3)."""
    n_map = surface.shading_normal(attrs)
    rho_s = surface.rho_s(attrs)
    E = np.zeros((len(n_map), 3))
    p = attrs["position"]
    origins = None
    for i in range(len(rig.lights)):
        L, Ei, dist = rig.incident(i, p)
        ndl = np.sum(n_map * L, axis=1)
        lit = ndl > 0.0
        if not lit.any():
            continue
        if origins is None and rig.lights[i]["cast_shadows"]:
            origins = surface.shadow_origin(attrs)
        vis = rig.visibility(i, attrs, L, dist, origins)
        f = np.where(lit, ndl, 0.0) * vis * surface.energy_transmitted(rho_s, np.clip(ndl, 0.0, 1.0))
        E += Ei * (f * bump_shadowing(attrs["normal_geo"], n_map, L))[:, None]
    _, frac = rig.ambient_visibility(attrs, blocked_sh=False)
    E += occluded_irradiance(surface.env_sh, n_map, frac) \
        * surface.energy_transmitted(rho_s, np.full(len(rho_s), 0.5))[:, None]
    mix = float(surface.material.mix)
    return E * surface.albedo(attrs) ** mix


def specular_and_exit(surface, rig, attrs, eye_mm):
    """At visible points: (specular (n, 3), exit factor albedo^(1 - mix) / pi * (1 - rho_s a(N.V, m)/pi)
    (n, 3)), as tsd/final.frag computes them (without the procedural pore normals)."""
    p = attrs["position"]
    ng = attrs["normal_geo"]
    n_map = surface.shading_normal(attrs)
    rho_s = surface.rho_s(attrs)
    m = float(surface.material.roughness)
    V = eye_mm[None, :] - p
    V /= np.maximum(np.linalg.norm(V, axis=1, keepdims=True), 1e-300)
    ndv = np.clip(np.sum(n_map * V, axis=1), 0.0, 1.0)
    spec = np.zeros((len(p), 3))
    origins = None
    for i in range(len(rig.lights)):
        L, Ei, dist = rig.incident(i, p)
        front = np.sum(ng * L, axis=1) > 0.0
        if not front.any():
            continue
        if origins is None and rig.lights[i]["cast_shadows"]:
            origins = surface.shadow_origin(attrs)
        vis = rig.visibility(i, attrs, L, dist, origins)
        ks = ksk_specular(n_map, L, V, m, rho_s)
        spec += Ei * (np.where(front, vis * ks, 0.0) * INV_PI)[:, None]
    # the environment's specular times the directional specular occlusion of the ray-cast blocked
    # directions' L2 SH (dermis.geometry.visibility.specular_occlusion_sh, as the techniques'): an HDR's
    # by Monte Carlo; a constant c's is c rho_s a / pi (surface.ambient(R) / pi = c exactly)
    rig.ambient_visibility(attrs)  # fills attrs["blocked_sh"]
    n_geo = ng / np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-300)
    R_mirror = 2.0 * np.sum(n_map * V, axis=1, keepdims=True) * n_map - V
    so = specular_occlusion_sh(R_mirror, n_geo, attrs["blocked_sh"])
    if surface.env_image is not None:
        spec += environment_specular_mc(surface.env_image, n_map, V, m, rho_s) * so[:, None]
    else:
        R = 2.0 * np.sum(n_map * V, axis=1, keepdims=True) * n_map - V
        a = surface.specular_albedo(ndv, m)
        spec += surface.ambient(R) * (INV_PI * rho_s * a * INV_PI * so)[:, None]
    mix = float(surface.material.mix)
    exit_factor = surface.albedo(attrs) ** (1.0 - mix) * INV_PI * surface.energy_transmitted(rho_s, ndv)[:, None]
    return spec, exit_factor


def _tangent_frames(n):
    """Orthonormal (t, b) about unit normals n (n, 3) (Duff et al. 2017, "Building an Orthonormal
    Basis, Revisited", listing 3)."""
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], 1)
    bb = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], 1)
    return t, bb


def environment_specular_mc(env_image, n, V, m: float, rho_s, samples: int = ENV_SPECULAR_SAMPLES,
                            seed: int = ENV_SPECULAR_SEED):
    """(1/pi) integral L(l) f_KSK(l, V) (n.l) dl over the hemisphere, L the equirect ``env_image``
    (bilinear, dermis.environment's orientation), f_KSK d'Eon's skin specular (dermis.specular,
    no 1/pi; the 1/pi makes it physical radiance). Monte Carlo with h drawn from the normalised
    Beckmann lobe (Walter et al. 2007, eq. 28: tan^2 theta_h = -m^2 ln(1 - xi1), phi = 2 pi xi2),
    l = reflect(-V, h), pdf(l) = P(h) (n.h) / (4 pi (V.h)); the weight f (n.l) / (pi pdf) is
    rho_s F(V.h) (n.l) / ((V.h) (n.h)) (the integrand of dermis.specular.rho_dt). ``samples``
    jittered strata per point (a square number), deterministic for a seed. Returns (n, 3)."""
    from dermis.specular import fresnel_schlick

    rho_s = np.broadcast_to(np.asarray(rho_s, np.float64), (len(n),))
    out = np.zeros((len(n), 3))
    lobe = lambda xi, c0, c1: 1.0 / np.sqrt(1.0 - m * m * np.log1p(-xi))  # Beckmann cos(theta_h)
    for c0, c1, cos_h, vh, nl, L in sampled_reflections(env_image, n, V, lobe, samples, seed):
        ok = (vh > 0.0) & (nl > 0.0)
        w = np.where(ok, fresnel_schlick(vh) * nl / np.where(ok, vh * cos_h, 1.0), 0.0)
        out[c0:c1] = rho_s[c0:c1, None] * np.mean(w[..., None] * L, axis=1)
    return out


def sampled_reflections(env_image, n, V, cos_theta_h, samples: int, seed: int):
    """The shared Monte Carlo loop of the environment's specular integrals: per chunk of points,
    ``samples`` jittered strata (a square number) of half vectors h about n with cos(theta_h) =
    ``cos_theta_h(xi1, c0, c1)`` (the lobe's inverse CDF) and phi = 2 pi xi2, the reflected
    directions l = reflect(-V, h) and the equirect's radiance along them (bilinear).
    Yields (c0, c1, cos_h, V.h, n.l, L), deterministic for a seed."""
    from dermis.prefiltered_environment import bilinear_equirect, direction_to_equirect

    s = int(round(np.sqrt(samples)))
    grid = np.stack(np.meshgrid(np.arange(s), np.arange(s), indexing="ij"), -1).reshape(1, -1, 2).astype(np.float64)
    for batch, c0 in enumerate(range(0, len(n), ENV_SPECULAR_CHUNK)):
        c1 = min(len(n), c0 + ENV_SPECULAR_CHUNK)
        nn, vv = n[c0:c1], V[c0:c1]
        rng = np.random.default_rng([seed, batch])
        xi = (grid + rng.random((c1 - c0, s * s, 2))) / s
        cos_h = cos_theta_h(xi[..., 0], c0, c1)
        sin_h = np.sqrt(np.maximum(1.0 - cos_h * cos_h, 0.0))
        phi = 2.0 * np.pi * xi[..., 1]
        t, b = _tangent_frames(nn)
        h = (sin_h * np.cos(phi))[..., None] * t[:, None] + (sin_h * np.sin(phi))[..., None] * b[:, None] \
            + cos_h[..., None] * nn[:, None]
        vh = np.sum(vv[:, None] * h, -1)
        l = 2.0 * vh[..., None] * h - vv[:, None]
        nl = np.sum(nn[:, None] * l, -1)
        u, v = direction_to_equirect(l.reshape(-1, 3))
        yield c0, c1, cos_h, vh, nl, bilinear_equirect(env_image, u, v).reshape(c1 - c0, s * s, 3)
