// Shadow maps for all lights, packed in one atlas: tile i holds light i's depth map.
// uShadowAtlas is a depth texture sampled with hardware comparison (each tap is itself a
// bilinear 2x2 PCF). The atlas is depth only: translucency comes from the thickness bake's far
// face (common/transmittance.glsl), not from a translucent shadow map.
#include "common/lights.glsl"

uniform mat4 uLightViewProj[MAX_LIGHTS];
uniform vec4 uShadowTile[MAX_LIGHTS];   // xy atlas offset, zw scale (atlas uv = off + uv * scale)
uniform vec4 uShadowParams[MAX_LIGHTS]; // x soft radius (texels), y depth bias, z normal offset (scene units), w = 1/tile size
uniform sampler2DShadow uShadowAtlas;

// Light-space coordinates: xy tile uv in [0,1], z depth in [0,1]; returns false outside the map.
bool shadow_coords(int i, vec3 P, vec3 N, out vec3 c) {
    vec4 q = uLightViewProj[i] * vec4(P + N * uShadowParams[i].z, 1.0);
    c = q.xyz / q.w * 0.5 + 0.5;
    return all(greaterThanEqual(c, vec3(0.0))) && all(lessThanEqual(c, vec3(1.0)));
}

float shadow_tap(int i, vec2 uv, float z) {
    vec2 h = vec2(0.5 * uShadowParams[i].w);  // stay half a texel inside the tile
    uv = clamp(uv, h, 1.0 - h);
    // explicit level 0 (the atlas has no mips): no implicit derivatives, which are undefined in the
    // non-uniform control flow of the callers (per-light loops with continue)
    return textureLod(uShadowAtlas, vec3(uShadowTile[i].xy + uv * uShadowTile[i].zw, z - uShadowParams[i].y), 0.0);
}

// Receiver-plane depth bias (Isidoro 2006, "Shadow Mapping: GPU-based Tips and Techniques", GDC):
// the light-space coordinates c of P itself and the depth gradient dz/d(uv) of P's tangent plane
// (normal N), so that a PCF tap at c.xy + delta compares against c.z + dot(dz, delta), the depth
// the receiver has THERE. A normal offset (King 2004) avoids acne by moving the lookup along N,
// which on a receiver grazed by the light shifts it sideways by up to the offset: where that
// crossed an occluder's silhouette in the map (the side view's eye socket behind the nose bridge,
// the nose wing) a lit blob several mm wide appeared inside the shadow. The gradient is clamped at
// a slope of MAX_RECEIVER_SLOPE (about 84 degrees), where N.L is ~0 anyway.
const float MAX_RECEIVER_SLOPE = 10.0;
bool shadow_receiver(int i, vec3 P, vec3 N, out vec3 c, out vec2 dz) {
    if (!shadow_coords(i, P, vec3(0.0), c)) return false;
    float h = max(uShadowParams[i].z, 1e-6);  // a few texels, scene units
    vec3 t1 = normalize(cross(N, abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 t2 = cross(N, t1);
    vec3 c1, c2, cl;
    shadow_coords(i, P + t1 * h, vec3(0.0), c1);
    shadow_coords(i, P + t2 * h, vec3(0.0), c2);
    vec3 L;
    light_incident(i, P, L);
    shadow_coords(i, P - L * h, vec3(0.0), cl);  // depth change over h straight along the light
    vec3 d1 = c1 - c, d2 = c2 - c;
    mat2 M = mat2(d1.x, d2.x, d1.y, d2.y);  // rows: d1.xy, d2.xy
    float det = determinant(M);
    float zl = abs(cl.z - c.z);              // depth of h along the light
    float xl = length((c1 - c).xy) + length((c2 - c).xy) + 1e-9;  // ~ uv of h across the light
    float gmax = MAX_RECEIVER_SLOPE * zl / (0.5 * xl);
    if (abs(det) < 1e-12) { dz = vec2(0.0); return true; }
    dz = inverse(transpose(M)) * vec2(d1.z, d2.z);
    float g = length(dz);
    if (g > gmax) dz *= gmax / g;
    return true;
}

// Sharp shadow (one bilinear-compare tap): for specular, d'Eon 2007 sec. 14.3.
float shadow_sharp(int i, vec3 P, vec3 N) {
    if (uLightRadiance[i].w < 0.5) return 1.0;
    vec3 c;
    vec2 dz;
    if (!shadow_receiver(i, P, N, c, dz)) return 1.0;
    // the bilinear 2x2 reaches one texel: bias by the receiver's slope over it
    return shadow_tap(i, c.xy, c.z - length(dz) * uShadowParams[i].w);
}

// Soft shadow: percentage-closer filtering over a disc of uShadowParams.x texels (Reeves 1987),
// 16 rotated Poisson taps, each a hardware 2x2 compare, each against the receiver plane's depth.
const vec2 POISSON16[16] = vec2[](
    vec2(-0.94201624, -0.39906216), vec2(0.94558609, -0.76890725), vec2(-0.09418410, -0.92938870),
    vec2(0.34495938, 0.29387760), vec2(-0.91588581, 0.45771432), vec2(-0.81544232, -0.87912464),
    vec2(-0.38277543, 0.27676845), vec2(0.97484398, 0.75648379), vec2(0.44323325, -0.97511554),
    vec2(0.53742981, -0.47373420), vec2(-0.26496911, -0.41893023), vec2(0.79197514, 0.19090188),
    vec2(-0.24188840, 0.99706507), vec2(-0.81409955, 0.91437590), vec2(0.19984126, 0.78641367),
    vec2(0.14383161, -0.14100790));

float shadow_soft(int i, vec3 P, vec3 N) {
    if (uLightRadiance[i].w < 0.5) return 1.0;
    vec3 c;
    vec2 dz;
    if (!shadow_receiver(i, P, N, c, dz)) return 1.0;
    float texel = uShadowParams[i].w;
    float z = c.z - 2.0 * length(dz) * texel;  // the bilinear 2x2 footprint of each tap, and curvature
    float radius = uShadowParams[i].x * texel;
    if (radius <= 0.0) return shadow_tap(i, c.xy, z);
    float sum = 0.0;
    for (int k = 0; k < 16; ++k) {
        vec2 delta = POISSON16[k] * radius;
        sum += shadow_tap(i, c.xy + delta, z + dot(dz, delta));
    }
    return sum / 16.0;
}

// The soft shadow and the width (mm, on the surface) of the penumbra it lies in, from the PCF
// taps themselves rather than from screen derivatives of s (which differ between GPUs: coarse
// or fine, quad by quad; preintegrated on an H100 vs llvmpipe: back-ears red 3% apart). The taps'
// values s_k at the map offsets delta_k give the least-squares gradient g of s in map uv,
//   g = C^-1 sum_k (s_k - mean s) delta_k,  C = sum_k (delta_k - mean delta)(delta_k - mean delta)^T,
// so s ramps across 1 / |g| of uv along g; the receiver's tangent plane (shadow_receiver's frame)
// maps that uv step back to the surface. 1e30 where the taps agree (no ramp within the disc).
float shadow_soft_penumbra(int i, vec3 P, vec3 N, out float width_mm) {
    width_mm = 1e30;
    if (uLightRadiance[i].w < 0.5) return 1.0;
    vec3 c;
    vec2 dz;
    if (!shadow_receiver(i, P, N, c, dz)) return 1.0;
    float texel = uShadowParams[i].w;
    float z = c.z - 2.0 * length(dz) * texel;
    float radius = uShadowParams[i].x * texel;
    if (radius <= 0.0) return shadow_tap(i, c.xy, z);
    float sum = 0.0;
    vec2 sd = vec2(0.0), d_mean = vec2(0.0);
    mat2 C = mat2(0.0);
    for (int k = 0; k < 16; ++k) {
        vec2 delta = POISSON16[k] * radius;
        float s = shadow_tap(i, c.xy + delta, z + dot(dz, delta));
        sum += s;
        sd += s * delta;
        d_mean += delta;
        C += outerProduct(delta, delta);
    }
    float s_mean = sum / 16.0;
    d_mean /= 16.0;
    C -= 16.0 * outerProduct(d_mean, d_mean);
    vec2 g = inverse(C) * (sd - 16.0 * s_mean * d_mean);  // ds per map uv
    float gl = length(g);
    if (gl <= 1e-6) return s_mean;
    // the tangent-plane step whose map projection is (1 / |g|) along g: J a = step, J's columns
    // the map uv moved by a unit step along two tangents (scene units)
    float h = max(uShadowParams[i].z, 1e-6);
    vec3 t1 = normalize(cross(N, abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 t2 = cross(N, t1);
    vec3 c1, c2;
    shadow_coords(i, P + t1 * h, vec3(0.0), c1);
    shadow_coords(i, P + t2 * h, vec3(0.0), c2);
    mat2 J = mat2((c1.xy - c.xy) / h, (c2.xy - c.xy) / h);
    float det = determinant(J);
    if (abs(det) < 1e-20) return s_mean;  // the light grazes the surface: the caller bounds it
    vec2 a = inverse(J) * (g / (gl * gl));
    width_mm = length(a) * uMmPerUnit;
    return s_mean;
}
