// Shadow maps for all lights, packed in one atlas: tile i holds light i's depth map.
// uShadowAtlas is a depth texture sampled with hardware comparison (each tap is itself a
// bilinear 2x2 PCF). The atlas is depth only: translucency comes from the thickness bake's far
// face (common/transmittance.glsl), not from a translucent shadow map.
#include "common/lights.glsl"

// The shadowing a normal map's tilted facets get from the smooth surface they stand on (Conty
// Estevez, Lecocq & Stein 2019, "A Microfacet-Based Shadowing Function to Solve the Bump Terminator
// Problem", Ray Tracing Gems, ch. 12): the mapped normal N, tilted by theta_d from the smooth
// (interpolated) normal Ns, is taken as one facet of a GGX microsurface about Ns whose roughness
// gives that tilt, alpha^2 = tan^2(theta_d) / 8 (eq. 12.3, at most 1), and the light's share that
// reaches it is Smith's G1 at theta_i, the light's angle to Ns (Walter et al. 2007, eq. 34:
// G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta_i))). Light below the smooth surface's horizon
// (Ns.L <= 0) reaches none of the microsurface the map stands for, however far N turns toward it
// (the terminator of a normal-mapped jaw otherwise lit through the head). 1 where N = Ns. Unitless,
// on a light's diffuse N.L; the caller has N.L > 0.
float bump_shadowing(vec3 Ns, vec3 N, vec3 L) {
    float cos_i = dot(Ns, L);
    if (cos_i <= 1e-6) return 0.0;
    float cos_d = min(dot(Ns, N), 1.0);
    if (cos_d >= 1.0 || cos_i >= 1.0) return 1.0;
    float alpha2 = clamp(0.125 * (1.0 / (cos_d * cos_d) - 1.0), 0.0, 1.0);
    float tan2_i = 1.0 / (cos_i * cos_i) - 1.0;
    return 2.0 / (1.0 + sqrt(1.0 + alpha2 * tan2_i));
}

uniform mat4 uLightViewProj[MAX_LIGHTS];
uniform vec4 uShadowTile[MAX_LIGHTS];   // xy atlas offset, zw scale (atlas uv = off + uv * scale)
uniform vec4 uShadowParams[MAX_LIGHTS]; // x soft radius (texels), y depth bias, z normal offset (scene units), w = 1/tile size
uniform sampler2DShadow uShadowAtlas;

// Light i's shadow filter, known at compile time where SKIN_SHADOW_FILTERS is defined (with
// SKIN_LIGHT_KINDS: "f0, f1, ...", dermis.gl.shadows.pcf_filter): SHADOW_FILTER_NONE the light
// casts no shadow, _PARABOLA / _BOX shadow_pcf_at's kernel for the light's softness (> 0), _RUNTIME
// decided from the uniforms as without the define. A constant index (DERMIS_FOR_EACH_LIGHT) then folds
// the other kernel's arithmetic and the single-tap branch of softness 0, which llvmpipe otherwise
// evaluates under a mask for every texel (benchmarks/results/round-24.md, irr24).
const int SHADOW_FILTER_RUNTIME = -1;
const int SHADOW_FILTER_NONE = 0;
const int SHADOW_FILTER_PARABOLA = 1;
const int SHADOW_FILTER_BOX = 2;
#ifdef SKIN_SHADOW_FILTERS
#ifndef SKIN_LIGHT_KINDS
#error "SKIN_SHADOW_FILTERS comes with SKIN_LIGHT_KINDS"
#endif
const int DERMIS_SHADOW_FILTERS[SKIN_LIGHT_COUNT] = int[SKIN_LIGHT_COUNT](SKIN_SHADOW_FILTERS);
int shadow_filter(int i) {
    return DERMIS_SHADOW_FILTERS[i];
}
#else
int shadow_filter(int i) {
    return SHADOW_FILTER_RUNTIME;
}
#endif

bool light_casts_shadow(int i) {
    int f = shadow_filter(i);
    return f == SHADOW_FILTER_RUNTIME ? !(uLightRadiance[i].w < 0.5) : f != SHADOW_FILTER_NONE;
}

float shadow_tap(int i, vec2 uv, float z) {
    vec2 h = vec2(0.5 * uShadowParams[i].w);  // stay half a texel inside the tile
    uv = clamp(uv, h, 1.0 - h);
    // explicit level 0 (the atlas has no mips): no implicit derivatives, which are undefined in the
    // non-uniform control flow of the callers (per-light loops with continue)
    return textureLod(uShadowAtlas, vec3(uShadowTile[i].xy + uv * uShadowTile[i].zw, z - uShadowParams[i].y), 0.0);
}

// Light-space coordinates c of P (xy tile uv in [0,1], z depth in [0,1]; false outside the map)
// and their Jacobian dc/dP: with q = M (P, 1), c = 0.5 q.xyz / q.w + 0.5, so dc/dP = 0.5 / q.w (A - (q.xyz / q.w) b^T),
// A = M's upper 3x3, b = (M[0].w, M[1].w, M[2].w) (b = 0 for a directional light's orthographic
// map: then exact finite differences; for a spot or point light the derivative at P itself).
// One transform instead of one per tangent step (the finite differences of rounds 1-4).
bool shadow_coords_jacobian(int i, vec3 P, out vec3 c, out mat3 J) {
    mat4 M = uLightViewProj[i];
    vec4 q = M * vec4(P, 1.0);
#ifdef SKIN_LIGHT_KINDS
    // a directional light's map is orthographic: M's last row is exactly (0, 0, 0, 1)
    // (dermis.camera.light_matrices: proj @ view, both of last row (0, 0, 0, 1), in float64, then
    // float32), so q.w = 1 and b = 0 exactly and the general form below gives these same floats
    // (tests/test_tsd_pipeline.py); a compile-time kind drops its divisions and outer product
    if (light_kind(i) == LIGHT_DIRECTIONAL) {
        c = q.xyz * 0.5 + 0.5;
        J = 0.5 * mat3(M);
        return all(greaterThanEqual(c, vec3(0.0))) && all(lessThanEqual(c, vec3(1.0)));
    }
#endif
    c = q.xyz / q.w * 0.5 + 0.5;
    vec3 b = vec3(M[0].w, M[1].w, M[2].w);
    J = (0.5 / q.w) * (mat3(M) - outerProduct(q.xyz / q.w, b));
    return all(greaterThanEqual(c, vec3(0.0))) && all(lessThanEqual(c, vec3(1.0)));
}

// Receiver-plane depth bias (Isidoro 2006, "Shadow Mapping: GPU-based Tips and Techniques", GDC):
// the light-space coordinates c of P itself and the depth gradient dz/d(uv) of P's tangent plane
// (normal N), so that a PCF tap at c.xy + delta compares against c.z + dot(dz, delta), the depth
// the receiver has THERE. A normal offset (King 2004) avoids acne by moving the lookup along N,
// which on a receiver grazed by the light shifts it sideways by up to the offset: where that
// crossed an occluder's silhouette in the map (the side view's eye socket behind the nose bridge,
// the nose wing) a lit blob several mm wide appeared inside the shadow. The gradient is clamped at
// a slope of MAX_RECEIVER_SLOPE (7: 81.9 degrees, N.L 0.141; a plane at N.L 0.15 stays exact,
// tests/test_shadow_pcf.py). graze (below) is set from the slope. T: the map uv that a
// unit step (scene units) along the tangent-plane axes t1, t2 moves (columns), for the penumbra
// width below. False for a light without a shadow map (uLightRadiance.w) or a point outside its map.
const float MAX_RECEIVER_SLOPE = 7.0;
// graze: how grazing the receiver is, 0 up to half the slope clamp (N.L >= 0.27), rising to 1 at the
// clamp (N.L <= 0.14); pcf_grid reads it.
// At a grazing receiver the PCF taps on the light's side compare against the receiver plane many
// texels of depth nearer the light (slope x (tap reach ~2.5 + the 2 |dz| footprint) texels: ~45 at the
// former clamp of 10), so an occluder that close in front goes unseen: in a concave fold under a
// cast shadow (the side scene's concha under the antihelix, the ear seen 3x closer, shadow tile
// 2048) the points at N.L 0-0.1 read a mean lit fraction 0.63 where a ray cast finds the antihelix
// (tests/test_shadow_leaks.py), a lit line along the terminator inside the shadow (preintegrated's
// "doubled edge": its wrap lights N.L ~ 0). A lower clamp alone trades that for self-shadowing of
// convex grazing receivers (the head's side terminator: the light's-side taps see the surface
// itself). Both come from the light's-side taps, so a grazing receiver's filter weighs them down:
// pcf_grid tilts its kernel along the depth gradient, to zero a third of the way to its light-side
// edge at graze = 1 (PCF_GRAZE_TILT); the taps beyond the receiver plane's far side still see
// an occluder in front and never the receiver's own surface. The penumbra of a grazing receiver is
// then narrower and shifted away from the light (where N.L < 0.27 scales the light): where a grazing
// receiver's shadow edge is cast from the light's side (the back of the back-ears concha under the
// helix, 3x closer) its lit side reaches a few pixels further than at shadow 8192. benchmarks/
// RESULTS.md round 19 (sizes19): the fold 0.63 -> 0.15; front-key at 768 px 6 pixels darker by > 10
// levels (the clamp 7 with a |dz.x| + |dz.y| footprint instead: 282; the light-side taps dropped by
// the sign of dot(dz, delta): blocky lit specks where a grazing shadow edge crosses texels).
// J: shadow_coords_jacobian's at P (shadow_box_curved lifts its taps along N with it).
struct ShadowReceiver {
    vec3 c;
    vec2 dz;
    mat2 T;
    mat3 J;
    float graze;
};
bool shadow_receiver(int i, vec3 P, vec3 N, out ShadowReceiver r) {
    r.c = vec3(0.0);
    r.dz = vec2(0.0);
    r.T = mat2(0.0);
    r.J = mat3(0.0);
    r.graze = 0.0;
    if (!light_casts_shadow(i)) return false;  // no map to read
    if (!shadow_coords_jacobian(i, P, r.c, r.J)) return false;
    mat3 J = r.J;
    vec3 t1 = normalize(cross(N, abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 t2 = cross(N, t1);
    vec3 L;
    light_incident(i, P, L);
    vec3 d1 = J * t1, d2 = J * t2;
    mat2 T = mat2(d1.xy, d2.xy);
    r.T = T;
    float zl = abs((J * L).z);  // depth of a unit step straight along the light
    float xl = length(d1.xy) + length(d2.xy) + 1e-9;  // ~ uv of a unit step across the light
    float gmax = MAX_RECEIVER_SLOPE * zl / (0.5 * xl);
    mat2 M = transpose(T);  // rows: d1.xy, d2.xy
    float det = determinant(M);
    float h = max(uShadowParams[i].z, 1e-6);  // rounds 1-4 stepped h (scene units): the same cut-off
    if (abs(det) * h * h < 1e-12) return true;  // the light grazes the plane: no usable gradient
    vec2 dz = inverse(M) * vec2(d1.z, d2.z);  // M dz = (d1.z, d2.z): rounds 1-4 solved with transpose(M), a wrong gradient wherever M is not symmetric
    float g = length(dz);
    r.graze = clamp(2.0 * g / gmax - 1.0, 0.0, 1.0);
    r.dz = g > gmax ? dz * (gmax / g) : dz;
    return true;
}

// Sharp shadow (one bilinear-compare tap): for specular, d'Eon 2007 sec. 14.3. c, dz: shadow_receiver's.
float shadow_sharp_at(int i, vec3 c, vec2 dz) {
    // the bilinear 2x2 reaches one texel: bias by the receiver's slope over it
    return shadow_tap(i, c.xy, c.z - length(dz) * uShadowParams[i].w);
}

float shadow_sharp(int i, vec3 P, vec3 N) {
    ShadowReceiver r;
    if (!shadow_receiver(i, P, N, r)) return 1.0;
    return shadow_sharp_at(i, r.c, r.dz);
}

// Soft shadow: percentage-closer filtering (Reeves 1987) with a disc of PCF_DISC_SCALE x
// uShadowParams.x texels, each point of it a bilinear compare: the penumbra across a straight edge
// is that disc's (tests/test_shadow_pcf.py, closed form). Rounds 1-5 took 16 Poisson taps (reaching
// |p| = 1.23, mean |p|^2 0.854: a disc of 1.307 x the radius). Here the taps are exact on the map's
// texel grid instead (Castano 2013, "Shadow mapping summary, part 1": "optimized PCF"): the filter
// is a weighted sum over the texels it covers with a SEPARABLE weight w(tx) w(ty), so two adjacent
// texels of each axis are one hardware bilinear-compare tap placed between them by their weights:
// n x n taps cover 2n x 2n texels. The 1-D weight is a parabola (Epanechnikov) integrated over
// each texel's cell, of the variance of the disc's marginal convolved with the bilinear tap's
// (R^2 / 4 + 1/6 = a^2 / 5 + 1/12); where the parabola does not fit the grid, a box of the same
// variance (Castano's uniform kernel). Against the disc filter (numpy, tests/test_shadow_pcf.py)
// the penumbra is within 0.004-0.026 over edge angles 0-45 degrees and softness 1-2 texels, where
// the 16 Poisson taps were 0.014-0.055 (softness 1-1.5): closer, with 9 taps instead of 16. The grid is 3 x 3 taps
// for every light, a compile-time count (unrolled, its arrays in registers: a per-light trip count
// measured slower than the 16 Poisson taps on llvmpipe, which runs every side of every branch under
// a mask: a 3 x 3 / 4 x 4 choice per light cost both, and 9 early-out probe taps before 16 cost
// 1459 ms against 1059, benchmarks/shadow_pcf_cost.py). It holds the default softness 1.5
// (parabola) and up to 2.1 texels exactly (box); a softer light's grid steps PCF_STRIDE > 1 texel
// per cell, no longer exact: at softness 3, 0.046-0.086 off the disc and 2-5% narrower (the Poisson
// taps: 0.054-0.072).
const float PCF_DISC_SCALE = 1.307;  // the Poisson set's disc: penumbrae as wide as rounds 1-5's

// antiderivative of the 1-D weight (unnormalised): a parabola 1 - x^2 / a^2, or a box, on [-a, a],
// times the tilt max(0, 1 + k x) (k = 0 untilted; the receiver graze's, pcf_grid): zero beyond x = -1 / k
float pcf_weight_cdf(float x, float a, bool box, float k) {
    float lo = k > 0.0 ? max(-a, -1.0 / k) : -a;
    float hi = k < 0.0 ? min(a, -1.0 / k) : a;
    x = clamp(x, lo, hi);
    float x2 = x * x;
    return box ? x + 0.5 * k * x2 : x - x2 * x / (3.0 * a * a) + k * (0.5 * x2 - 0.25 * x2 * x2 / (a * a));
}

const float PCF_GRAZE_TILT = 3.0;  // a grazing kernel's weight is 0 from a / 3 on its light side (ShadowReceiver.graze)
const int PCF_GRID = 3;  // taps per axis: 2 x PCF_GRID cells hold any weight of half-width a < PCF_GRID - 0.5

// PCF over the 2n x 2n cells (of ``stride`` texels, 1 where exact) from the one whose cell
// [t - 0.5, t + 0.5) holds pc - a on each axis (pc: the filter's centre in cell-centre
// coordinates). Returns the weighted mean; with want_width also the sums of the least-squares
// gradient below. graze: the receiver's (ShadowReceiver).
float pcf_grid(int i, vec2 c, float z, vec2 dz, float graze, float a, bool box, float stride, bool want_width,
               out float wsum, out vec2 sd, out vec2 dsum, out mat2 C) {
    const int n = PCF_GRID;
    float texel = uShadowParams[i].w;
    vec2 pc = (c / texel - 0.5) / stride;
    vec2 t0 = floor(pc - a + 0.5);
    vec2 pos[n], w[n];
    // a grazing receiver's kernel tilts along the receiver's depth gradient (graze, shadow_receiver
    // above): per axis max(0, 1 + k x), k = PCF_GRAZE_TILT graze dz_hat / a, a separable
    // ramp integrated over each cell like the kernel itself, so the weights stay continuous as the
    // filter moves across texels (dropping the light-side taps by sign drew blocky specks)
    float gl = length(dz);
    vec2 tilt = gl > 0.0 ? PCF_GRAZE_TILT * graze * dz / (gl * a) : vec2(0.0);
    vec2 lo = vec2(pcf_weight_cdf(t0.x - 0.5 - pc.x, a, box, tilt.x), pcf_weight_cdf(t0.y - 0.5 - pc.y, a, box, tilt.y));
    for (int k = 0; k < n; ++k) {
        vec2 ta = t0 + float(2 * k);
        vec2 mid = vec2(pcf_weight_cdf(ta.x + 0.5 - pc.x, a, box, tilt.x), pcf_weight_cdf(ta.y + 0.5 - pc.y, a, box, tilt.y));
        vec2 hi = vec2(pcf_weight_cdf(ta.x + 1.5 - pc.x, a, box, tilt.x), pcf_weight_cdf(ta.y + 1.5 - pc.y, a, box, tilt.y));
        w[k] = hi - lo;
        pos[k] = (ta + (hi - mid) / max(w[k], vec2(1e-12)) - pc) * (stride * texel);  // bilinear weighs ta, ta+1 as (mid-lo) : (hi-mid)
        lo = hi;
    }
    float sum = 0.0;
    wsum = 0.0;
    sd = dsum = vec2(0.0);
    C = mat2(0.0);
    for (int ky = 0; ky < n; ++ky) {
        for (int kx = 0; kx < n; ++kx) {
            vec2 delta = vec2(pos[kx].x, pos[ky].y);
            float wk = w[kx].x * w[ky].y;
            float s = shadow_tap(i, c + delta, z + dot(dz, delta));
            sum += wk * s;
            wsum += wk;
            if (want_width) {
                sd += wk * s * delta;
                dsum += wk * delta;
                C += wk * outerProduct(delta, delta);
            }
        }
    }
    return sum / wsum;
}

// The soft shadow and, when want_width, the width (mm, on the surface) of the penumbra it lies in,
// from the PCF taps themselves rather than from screen derivatives of s (which differ between
// GPUs: coarse or fine, quad by quad; preintegrated on an H100 vs llvmpipe: back-ears red 3%
// apart). The taps' values s_k at the map offsets delta_k, weights W_k, give the weighted
// least-squares gradient g of s in map uv,
//   g = C^-1 sum_k W_k (s_k - mean s) delta_k,  C = sum_k W_k (delta_k - mean delta)(delta_k - mean delta)^T,
// so s ramps across 1 / |g| of uv along g; the receiver's tangent plane (T of shadow_receiver)
// maps that uv step back to the surface. width_mm = 1e30 where the taps agree (no ramp).
// r: shadow_receiver's, for a light that casts shadows and a receiver inside its map.
float shadow_pcf_at(int i, ShadowReceiver r, bool want_width, out float width_mm) {
    width_mm = 1e30;
    vec3 c = r.c;
    vec2 dz = r.dz;
    float z = c.z - 2.0 * length(dz) * uShadowParams[i].w;  // the bilinear 2x2 footprint of each tap, and curvature
    float R = PCF_DISC_SCALE * uShadowParams[i].x;  // the disc's radius, texels
    int kernel = shadow_filter(i);
    if (kernel == SHADOW_FILTER_RUNTIME && R <= 0.0) return shadow_tap(i, c.xy, z);  // a known kernel has R > 0
    // per light (uniform): the half-widths (texels) of the same variance; the parabola where the
    // grid holds it, else the box; a box wider than the grid strides its cells over the texels
    float a_par = sqrt(5.0 * (0.25 * R * R + 1.0 / 12.0));
    float a_box = 0.5 * sqrt(3.0 * R * R + 1.0);
    const float fit = float(PCF_GRID) - 0.51;
    bool box = kernel == SHADOW_FILTER_RUNTIME ? a_par >= fit : kernel == SHADOW_FILTER_BOX;
    float a = box ? a_box : a_par;
    // a known parabola has a < fit (dermis.gl.shadows.pcf_filter, by a margin): stride 1 exactly, as max() gives
    float stride = kernel == SHADOW_FILTER_PARABOLA ? 1.0 : max(a / fit, 1.0);
    float wsum;
    vec2 sd, dsum;
    mat2 C;
    float s_mean = pcf_grid(i, c.xy, z, dz, r.graze, a / stride, box, stride, want_width, wsum, sd, dsum, C);
    if (!want_width) return s_mean;
    vec2 d_mean = dsum / wsum;
    C -= wsum * outerProduct(d_mean, d_mean);
    vec2 g = inverse(C) * (sd - wsum * s_mean * d_mean);  // ds per map uv
    float gl = length(g);
    if (gl <= 1e-6) return s_mean;
    // the tangent-plane step a whose map projection is (1 / |g|) along g: T a = step
    if (abs(determinant(r.T)) < 1e-20) return s_mean;  // the light grazes the surface: the caller bounds it
    vec2 step_t = inverse(r.T) * (g / (gl * gl));
    width_mm = length(step_t) * uMmPerUnit;
    return s_mean;
}

float shadow_pcf(int i, vec3 P, vec3 N, bool want_width, out float width_mm) {
    width_mm = 1e30;
    ShadowReceiver r;
    if (!shadow_receiver(i, P, N, r)) return 1.0;
    return shadow_pcf_at(i, r, want_width, width_mm);
}

float shadow_soft(int i, vec3 P, vec3 N) {
    float unused;
    return shadow_pcf(i, P, N, false, unused);
}

float shadow_soft_penumbra(int i, vec3 P, vec3 N, out float width_mm) {
    return shadow_pcf(i, P, N, true, width_mm);
}

// shadow_box_curved (below) with kappa = 0: the shadow box-filtered over a square of half-width half_mm (mm) of P's tangent plane (normal N):
// the mean of SHADOW_BOX_GRID^2 bilinear-compare taps at the cell midpoints of the square, each compared
// against the receiver plane's own depth there (shadow_receiver's gradient). For light that entered a
// thin part's far face anywhere within the square (a box of per-axis variance half_mm^2 / 3, in any
// orientation; common/transmittance.glsl), not a light's penumbra. The taps are many texels apart, and
// each switches within one texel, so the mean across a straight shadow edge is a staircase with one step
// per distinct distance of a tap from the edge: on an axis-aligned grid 7 levels for an edge along an
// axis (steps of 1/6: bands; tests/test_translucency_oblique.py). The grid is turned by atan(1/6)
// (a rotated grid, as multisampling's): the 36 taps' projections on either axis are then distinct and
// evenly spaced (i - j / 6), and on the diagonals distinct ((7 i + 5 j) / 6), so such an edge steps by
// 1/36. pcf_grid's exact 3 x 3 weights stride past whole texels once the square is wider than ~5 texels:
// over the back-lit scapha (back-ears, 768 px, the square 3-4 mm wide, ~25 texels at shadow 2048) its
// 9 taps drew speckles in preintegrated; this grid at 4 x 4 faint blotches, 6 x 6 and 8 x 8 smooth.
// 1 where the light casts no shadow.
const int SHADOW_BOX_GRID = 6;
const vec2 SHADOW_BOX_TURN = vec2(6.0, 1.0) / 6.0827625;  // (cos, sin) of atan(1/6); 6.0827625 = sqrt(37)
// The turned grid's tap at cell g (in [-1, 1]^2 of the unturned square): its offset in units of the half-width
#define SHADOW_BOX_OFFSET(g) vec2(SHADOW_BOX_TURN.x * (g).x - SHADOW_BOX_TURN.y * (g).y, SHADOW_BOX_TURN.y * (g).x + SHADOW_BOX_TURN.x * (g).y)
//
// shadow_box_curved: the same over a receiver that is not a plane: each tap compares against the
// tangent plane lifted along N by the rise kappa r^2 / 2 (mm) that a concave quadric of curvature
// kappa (1/mm, unsigned: the larger lift of the two signs) has at the tap's distance r from P, in
// map depth h ((J N).z - dz . (J N).xy) (N moves the uv as well as the depth). Without it a box
// millimetres wide on a concave surface (an eye socket, the nose's side) compares against a plane the
// surface itself rises above and calls its own surface an occluder. kappa = 0: the plane's box (above).
// probe in [0, 1]: a shadow value at P known to the caller (its PCF); where the square's four corner
// taps and it are all 1 (all 0) the box returns 1 (0) without the other 32 taps. A shadow that
// touches neither the corners nor the PCF's disc is then missed (a speck narrower than the gaps,
// ~0.2 of the square's side). probe < 0: no probe.
// The rise (map depth) to compare at the tap f: r2 |f'|^2 at f' = f - shift r2 |f|^2, the shift at most
// half of |f| (a grazing receiver, T near singular: no fixed point to step to).
float lifted_rise(vec2 f, vec2 shift, float r2) {
    vec2 d = shift * (r2 * dot(f, f));
    float lim = 0.5 * length(f);
    vec2 g = f - (dot(d, d) > lim * lim ? d * (lim / length(d)) : d);
    return r2 * dot(g, g);
}

float shadow_box_curved(int i, vec3 P, vec3 N, float half_mm, float curvature_per_mm, float probe) {
    ShadowReceiver r;
    if (!shadow_receiver(i, P, N, r)) return 1.0;
    vec3 c = r.c;
    vec2 dz = r.dz;
    mat2 T = r.T;
    vec3 jn = r.J * N;
    float depth_per_mm = abs(jn.z - dot(dz, jn.xy)) / uMmPerUnit;  // map depth of a step along N off the plane
    float rise_per_mm2 = 0.5 * curvature_per_mm * depth_per_mm;  // map depth per mm^2 of r^2
    // f per map depth of rise: lifting by l mm along N moves the uv by (J N).xy l / mm_per_unit, a tangent
    // offset of T^-1 (J N).xy l (mm), so the lifted surface seen at a tap's uv is the one over f' = f - that
    // offset / half_mm, whose rise is the one to compare (lifted_rise; one fixed-point step). With the rise
    // at f itself the wide penumbra's 4.2 mm square (round 21, wide21: 3.4 mm before) shadowed a trough's
    // wall lit at N.L = 0.5, 2 of 36 taps (tests/test_preintegrated.py); the offset, 0.5 mm at its corners.
    float detT = determinant(T);
    vec2 shift = abs(detT) > 1e-12 && depth_per_mm > 0.0 ? inverse(T) * jn.xy / (half_mm * depth_per_mm) : vec2(0.0);
    vec2 e1 = T[0] * (half_mm / uMmPerUnit), e2 = T[1] * (half_mm / uMmPerUnit);  // map uv of the square's half-axes
    float z = c.z - 2.0 * length(dz) * uShadowParams[i].w;  // the bilinear 2x2 footprint, as shadow_pcf_at
    float r2 = rise_per_mm2 * half_mm * half_mm;  // map depth of the rise at |f| = 1
    if (probe == 0.0 || probe == 1.0) {
        float g = 1.0 - 1.0 / float(SHADOW_BOX_GRID);  // the outermost taps' cell midpoints
        float corners = 0.0;
        for (int k = 0; k < 4; ++k) {
            vec2 gk = vec2((k & 1) == 0 ? -g : g, k < 2 ? -g : g);
            vec2 f = SHADOW_BOX_OFFSET(gk);
            vec2 delta = f.x * e1 + f.y * e2;
            corners += shadow_tap(i, c.xy + delta, z + dot(dz, delta) - lifted_rise(f, shift, r2));
        }
        if (corners == 4.0 * probe) return probe;
    }
    float sum = 0.0;
    for (int ky = 0; ky < SHADOW_BOX_GRID; ++ky) {
        for (int kx = 0; kx < SHADOW_BOX_GRID; ++kx) {
            vec2 g = (vec2(kx, ky) + 0.5) * (2.0 / float(SHADOW_BOX_GRID)) - 1.0;
            vec2 f = SHADOW_BOX_OFFSET(g);
            vec2 delta = f.x * e1 + f.y * e2;
            sum += shadow_tap(i, c.xy + delta, z + dot(dz, delta) - lifted_rise(f, shift, r2));
        }
    }
    return sum / float(SHADOW_BOX_GRID * SHADOW_BOX_GRID);
}

// The soft shadow (shadow_soft) and the sharp one (shadow_sharp) of light i from ONE receiver
// solve; the soft one only where want_soft (the caller's N.L > 0). For tsd's texture-space
// irradiance pass, which stores the sharp shadow for the final pass's specular (d'Eon & Luebke
// 2007, 14.5.2: the shadow computed once in texture space and reused).
float shadow_soft_and_sharp(int i, vec3 P, vec3 N, bool want_soft, out float sharp) {
    sharp = 1.0;
    ShadowReceiver r;
    if (!shadow_receiver(i, P, N, r)) return 1.0;
    sharp = shadow_sharp_at(i, r.c, r.dz);
    float unused;
    return want_soft ? shadow_pcf_at(i, r, false, unused) : 1.0;
}
