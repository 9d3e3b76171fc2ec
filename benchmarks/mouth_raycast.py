"""front-key's mouth line and lid crease: the skin-to-skin bounce's gather and the ambient occlusion against a ray
cast at the pixels' own surface points (issue 12, round 23, mouth23).

    PYTHONPATH=src python benchmarks/mouth_raycast.py      (~1 min)
Per box (box_red.py's), the one-bounce irradiance of the key light alone, red, E_b = (1/K) sum rho(y_k) E(y_k), E the
key light's 3.0 x N.L x ray-cast shadow, rho the albedo map at y (dermis.blender.validate._albedo_at): (a) 512 fresh
cosine rays from each pixel's own point (the reference), (b) dermis.geometry.interreflection's per-vertex bake (its
stored hits) interpolated over the pixel's triangle (what the renderer gathers, with E evaluated at the exact hits),
(c) fresh rays from the same vertices. And the cosine-weighted ambient occlusion at the pixels (512 rays) against
dermis.geometry.visibility's per-vertex bake interpolated (= the constant environment's visible fraction).
"""
import sys, numpy as np
sys.path.insert(0, "benchmarks")
import mouth_terms, helix_glow
from box_red import BOXES
from dermis.geometry import interreflection as IR
from dermis.geometry.raycast import cosine_directions
from dermis.geometry.visibility import OFFSET_REL
from dermis.blender.validate import _albedo_at
sc = mouth_terms._scene()
L = -np.asarray(sc.lights[0].direction, float); L /= np.linalg.norm(L)
P = np.asarray(sc.mesh.positions, float); I = np.asarray(sc.mesh.indices, np.int64).reshape(-1, 3); N = np.asarray(sc.mesh.normals, float)
diag = np.linalg.norm(P.max(0) - P.min(0)); mm = sc.mm_per_unit
hits = IR.mesh_hits(sc.mesh)
print("bake rays", hits.rays, "cached", hits.cached, "diag mm", diag * mm)
rng = np.random.default_rng(1)

def exitant(rc, tri, b):
    """rho E (red) at surface points: key light 3.0 x N.L x ray-cast shadow (no environment)."""
    ok = tri >= 0
    t = np.maximum(tri, 0)
    w = np.stack([1 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
    p = np.einsum("ij,ijk->ik", w, P[I[t]]); n = np.einsum("ij,ijk->ik", w, N[I[t]]); n /= np.linalg.norm(n, axis=1, keepdims=True)
    ndl = n @ L
    vis = ~rc.occluded(p + n * OFFSET_REL * diag, np.broadcast_to(L, p.shape).copy(), 0.0)
    rho = _albedo_at(sc, t, b)[:, 0]
    return np.where(ok, rho * 3.0 * np.maximum(ndl, 0) * vis, 0.0)

for name, box in BOXES["front-key"].items():
    x0, y0, x1, y1 = box
    rc, d, p, tri, b, n, _ = helix_glow.camera_hits(sc, (x0, y0, x1 + 1, y1 + 1))
    ok = tri >= 0; p, tri, b, n, d = p[ok], tri[ok], b[ok], n[ok], d[ok]
    K = 512
    # reference: fresh cosine rays from each pixel's own surface point (the interpolated normal)
    dirs = cosine_directions(np.repeat(n, 1, 0), rng.random((len(n), K)), rng.random((len(n), K))).reshape(-1, 3)
    o = np.repeat(p + n * OFFSET_REL * diag, K, 0)
    htri, hb = IR._first_front_hits(rc, o, dirs, I, N, IR.NEAR_REL * diag)
    eb_ref = exitant(rc, htri, hb).reshape(-1, K).mean(1)
    # the bake: per-vertex gather over its stored hits, interpolated over the pixel's triangle
    vs = np.unique(I[tri])
    ev = np.zeros(len(P))
    for v in vs:
        ev[v] = exitant(rc, hits.triangle[v].astype(np.int64), hits.barycentric[v].astype(np.float64)).mean()
    w = np.stack([1 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
    eb_bake = (w * ev[I[tri]]).sum(1)
    # at the pixels' vertices with fresh rays from the vertex (the bake's quantity, re-drawn)
    Pv, Nv = P[vs], N[vs]
    dv = cosine_directions(Nv, rng.random((len(vs), K)), rng.random((len(vs), K))).reshape(-1, 3)
    vt, vb = IR._first_front_hits(rc, np.repeat(Pv + Nv * OFFSET_REL * diag, K, 0), dv, I, N, IR.NEAR_REL * diag)
    ev2 = np.zeros(len(P)); ev2[vs] = exitant(rc, vt, vb).reshape(-1, K).mean(1)
    eb_bake2 = (w * ev2[I[tri]]).sum(1)
    e_dir = exitant(rc, tri, b) / np.maximum(_albedo_at(sc, tri, b)[:, 0], 1e-9)
    edges = np.linalg.norm(P[I[tri]][:, [0, 1, 2]] - P[I[tri]][:, [1, 2, 0]], axis=2).mean() * mm
    print(f"{name}: {len(p)} px, {len(vs)} vertices, mean edge {edges:.2f} mm, N.V {np.median(-(n*d).sum(1)):.2f}; "
          f"direct E red {e_dir.mean():.4f}; one-bounce E_b (red, key light only): at the pixels (ray cast) {eb_ref.mean():.4f}"
          f" | per vertex, bake's hits, interpolated {eb_bake.mean():.4f} ({eb_bake.mean()/eb_ref.mean():.2f}x)"
          f" | per vertex, fresh rays {eb_bake2.mean():.4f} ({eb_bake2.mean()/eb_ref.mean():.2f}x)")
    print("   per-vertex E_b at the pixels' vertices:", np.round(ev[vs], 3), "positions y(mm)", np.round(P[vs, 1] * mm, 1))

from dermis.geometry.visibility import mesh_visibility
vis = mesh_visibility(sc.mesh)
A = np.asarray(vis.ao, float).reshape(len(P), -1)[:, 0]
for name, box in BOXES["front-key"].items():
    x0, y0, x1, y1 = box
    rc, d, p, tri, b, n, _ = helix_glow.camera_hits(sc, (x0, y0, x1 + 1, y1 + 1))
    ok = tri >= 0; p, tri, b, n = p[ok], tri[ok], b[ok], n[ok]
    K = 512
    dirs = cosine_directions(n, rng.random((len(n), K)), rng.random((len(n), K))).reshape(-1, 3)
    occ = rc.occluded(np.repeat(p + n * OFFSET_REL * diag, K, 0), dirs, 0.0).reshape(-1, K)
    w = np.stack([1 - b[:, 0] - b[:, 1], b[:, 0], b[:, 1]], 1)
    print(f"{name}: AO at the pixels (ray cast, 512 rays) {1 - occ.mean():.3f}; per-vertex bake interpolated {(w * A[I[tri]]).sum(1).mean():.3f}")
