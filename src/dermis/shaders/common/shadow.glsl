// Shadow maps for all lights, packed in one atlas: tile i holds light i's depth map.
// uShadowAtlas is a depth texture sampled with hardware comparison (each tap is itself a
// bilinear 2x2 PCF). The atlas is depth only: translucency comes from the thickness bake's far
// face (common/transmittance.glsl), not from a translucent shadow map.
#include "common/lights.glsl"

uniform mat4 uLightViewProj[MAX_LIGHTS];
uniform vec4 uShadowTile[MAX_LIGHTS];   // xy atlas offset, zw scale (atlas uv = off + uv * scale)
uniform vec4 uShadowParams[MAX_LIGHTS]; // x soft radius (texels), y depth bias, z normal offset (scene units), w = 1/tile size
uniform sampler2DShadow uShadowAtlas;

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
// a slope of MAX_RECEIVER_SLOPE (about 84 degrees), where N.L is ~0 anyway. T: the map uv that a
// unit step (scene units) along the tangent-plane axes t1, t2 moves (columns), for the penumbra
// width below.
const float MAX_RECEIVER_SLOPE = 10.0;
bool shadow_receiver(int i, vec3 P, vec3 N, out vec3 c, out vec2 dz, out mat2 T) {
    mat3 J;
    dz = vec2(0.0);
    T = mat2(0.0);
    if (!shadow_coords_jacobian(i, P, c, J)) return false;
    vec3 t1 = normalize(cross(N, abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 t2 = cross(N, t1);
    vec3 L;
    light_incident(i, P, L);
    vec3 d1 = J * t1, d2 = J * t2;
    T = mat2(d1.xy, d2.xy);
    float zl = abs((J * L).z);  // depth of a unit step straight along the light
    float xl = length(d1.xy) + length(d2.xy) + 1e-9;  // ~ uv of a unit step across the light
    float gmax = MAX_RECEIVER_SLOPE * zl / (0.5 * xl);
    mat2 M = transpose(T);  // rows: d1.xy, d2.xy
    float det = determinant(M);
    float h = max(uShadowParams[i].z, 1e-6);  // rounds 1-4 stepped h (scene units): the same cut-off
    if (abs(det) * h * h < 1e-12) return true;  // the light grazes the plane: no usable gradient
    dz = inverse(M) * vec2(d1.z, d2.z);  // M dz = (d1.z, d2.z): rounds 1-4 solved with transpose(M), a wrong gradient wherever M is not symmetric
    float g = length(dz);
    if (g > gmax) dz *= gmax / g;
    return true;
}

// Sharp shadow (one bilinear-compare tap): for specular, d'Eon 2007 sec. 14.3.
float shadow_sharp(int i, vec3 P, vec3 N) {
    if (uLightRadiance[i].w < 0.5) return 1.0;
    vec3 c;
    vec2 dz;
    mat2 T;
    if (!shadow_receiver(i, P, N, c, dz, T)) return 1.0;
    // the bilinear 2x2 reaches one texel: bias by the receiver's slope over it
    return shadow_tap(i, c.xy, c.z - length(dz) * uShadowParams[i].w);
}

// Soft shadow: percentage-closer filtering over a disc of uShadowParams.x texels (Reeves 1987),
// 16 Poisson taps, each a hardware 2x2 compare, each against the receiver plane's depth. The
// points reach |p| = 1.23 (mean |p|^2 0.854): the kernel is a uniform disc of about 1.31 x the
// radius (tests/test_shadow_pcf.py: the penumbra across an edge within 0.02 of that disc's).
// No early out: on llvmpipe a branch runs both sides under a mask whenever one lane of a SIMD
// block takes it, and 9 probe taps before the 16 (skipped only where all 9 agree) measured 1459
// ms against 1059 without (tsd irradiance 512^2, load 9; benchmarks/shadow_pcf_cost.py).
const int PCF_TAPS = 16;
const vec2 POISSON16[16] = vec2[](
    vec2(-0.94201624, -0.39906216), vec2(0.94558609, -0.76890725), vec2(-0.09418410, -0.92938870),
    vec2(0.34495938, 0.29387760), vec2(-0.91588581, 0.45771432), vec2(-0.81544232, -0.87912464),
    vec2(-0.38277543, 0.27676845), vec2(0.97484398, 0.75648379), vec2(0.44323325, -0.97511554),
    vec2(0.53742981, -0.47373420), vec2(-0.26496911, -0.41893023), vec2(0.79197514, 0.19090188),
    vec2(-0.24188840, 0.99706507), vec2(-0.81409955, 0.91437590), vec2(0.19984126, 0.78641367),
    vec2(0.14383161, -0.14100790));

// The soft shadow and, when want_width, the width (mm, on the surface) of the penumbra it lies in,
// from the PCF taps themselves rather than from screen derivatives of s (which differ between
// GPUs: coarse or fine, quad by quad; preintegrated on an H100 vs llvmpipe: back-ears red 3%
// apart). The taps' values s_k at the map offsets delta_k give the least-squares gradient g of s
// in map uv,
//   g = C^-1 sum_k (s_k - mean s) delta_k,  C = sum_k (delta_k - mean delta)(delta_k - mean delta)^T,
// so s ramps across 1 / |g| of uv along g; the receiver's tangent plane (T of shadow_receiver)
// maps that uv step back to the surface. width_mm = 1e30 where the taps agree (no ramp).
float shadow_pcf(int i, vec3 P, vec3 N, bool want_width, out float width_mm) {
    width_mm = 1e30;
    if (uLightRadiance[i].w < 0.5) return 1.0;
    vec3 c;
    vec2 dz;
    mat2 T;
    if (!shadow_receiver(i, P, N, c, dz, T)) return 1.0;
    float texel = uShadowParams[i].w;
    float z = c.z - 2.0 * length(dz) * texel;  // the bilinear 2x2 footprint of each tap, and curvature
    float radius = uShadowParams[i].x * texel;
    if (radius <= 0.0) return shadow_tap(i, c.xy, z);
    float sum = 0.0;
    vec2 sd = vec2(0.0);
    for (int k = 0; k < PCF_TAPS; ++k) {
        vec2 delta = POISSON16[k] * radius;
        float s = shadow_tap(i, c.xy + delta, z + dot(dz, delta));
        sum += s;
        sd += s * delta;
    }
    float s_mean = sum / float(PCF_TAPS);
    if (!want_width) return s_mean;
    vec2 d_mean = vec2(0.0);
    mat2 C = mat2(0.0);
    for (int k = 0; k < PCF_TAPS; ++k) {
        vec2 delta = POISSON16[k] * radius;
        d_mean += delta;
        C += outerProduct(delta, delta);
    }
    d_mean /= float(PCF_TAPS);
    C -= float(PCF_TAPS) * outerProduct(d_mean, d_mean);
    vec2 g = inverse(C) * (sd - float(PCF_TAPS) * s_mean * d_mean);  // ds per map uv
    float gl = length(g);
    if (gl <= 1e-6) return s_mean;
    // the tangent-plane step a whose map projection is (1 / |g|) along g: T a = step
    if (abs(determinant(T)) < 1e-20) return s_mean;  // the light grazes the surface: the caller bounds it
    vec2 a = inverse(T) * (g / (gl * gl));
    width_mm = length(a) * uMmPerUnit;
    return s_mean;
}

float shadow_soft(int i, vec3 P, vec3 N) {
    float unused;
    return shadow_pcf(i, P, N, false, unused);
}

float shadow_soft_penumbra(int i, vec3 P, vec3 N, out float width_mm) {
    return shadow_pcf(i, P, N, true, width_mm);
}
