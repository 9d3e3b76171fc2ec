// Punctual lights shared by every technique. Units: positions in scene units; radiance linear RGB.
// A directional light's intensity is the irradiance it gives at normal incidence; a point or spot
// light's intensity is per steradian, with inverse-square falloff over the distance in METRES
// (uMmPerUnit converts), so a scene's scale changes nothing but its size.
// MAX_LIGHTS and LIGHT_DIRECTIONAL / _POINT / _SPOT come from dermis.techniques.shared.
#include "common/constants.glsl"

uniform int uLightCount;
uniform vec4 uLightPosType[MAX_LIGHTS];   // xyz position, w type
uniform vec4 uLightDir[MAX_LIGHTS];       // xyz direction of travel (unit), w unused
uniform vec4 uLightRadiance[MAX_LIGHTS];  // rgb colour * intensity, w = casts shadows (0/1)
uniform vec4 uLightSpot[MAX_LIGHTS];      // x cos(outer half-angle), y cos(inner), z/w unused
uniform float uMmPerUnit;

// Light i's kind (LIGHT_DIRECTIONAL / _POINT / _SPOT). With SKIN_LIGHT_KINDS defined (beside
// SKIN_LIGHT_COUNT: the scene's kinds as "k0, k1, ...";
// dermis.techniques.shared.light_signature), a constant wherever i is one (DERMIS_FOR_EACH_LIGHT's
// light_i), so the other kinds' arithmetic folds away at compile time: llvmpipe runs both sides of a
// branch, even one on a uniform, under a lane mask (benchmarks/results/round-24.md, irr24: tsd's
// irradiance pass -7 ms of 133 on the head's three directional lights). Else read from uLightPosType.w.
#ifdef SKIN_LIGHT_KINDS
#ifndef SKIN_LIGHT_COUNT
#error "SKIN_LIGHT_KINDS needs SKIN_LIGHT_COUNT"
#endif
const int DERMIS_LIGHT_KINDS[SKIN_LIGHT_COUNT] = int[SKIN_LIGHT_COUNT](SKIN_LIGHT_KINDS);
int light_kind(int i) {
    return DERMIS_LIGHT_KINDS[i];  // every kind is known (dermis.techniques.shared.light_signature)
}
#else
int light_kind(int i) {
    return int(uLightPosType[i].w + 0.5);
}
#endif

// Direction to the light (unit) and the irradiance it brings at normal incidence, at point P.
vec3 light_incident(int i, vec3 P, out vec3 L) {
    int type = light_kind(i);
    vec3 E = uLightRadiance[i].rgb;
    if (type == LIGHT_DIRECTIONAL) {
        L = -uLightDir[i].xyz;
        return E;
    }
    vec3 d = uLightPosType[i].xyz - P;
    float dist_m = max(length(d) * uMmPerUnit * 1e-3, 1e-4);
    L = normalize(d);
    E /= dist_m * dist_m;  // inverse-square law
    if (type == LIGHT_SPOT) {
        float c = dot(-L, uLightDir[i].xyz);
        E *= smoothstep(uLightSpot[i].x, uLightSpot[i].y, c);
    }
    return E;
}

// DERMIS_FOR_EACH_LIGHT(STMT): STMT once per light, with `light_i` its index. Without
// SKIN_LIGHT_COUNT, a loop over uLightCount (any count). With SKIN_LIGHT_COUNT = n defined (0..8,
// the scene's light count: dermis.techniques.shared.LightCountPrograms compiles one program per
// count), STMT written out n times with light_i a CONSTANT (a const int in its own block), so every
// index into the light uniforms (uLightPosType[i], uLightViewProj[i], ...) is known at compile time:
// on llvmpipe that made tsd's irradiance pass 15-30% and lambert's pass ~20% cheaper than the loop,
// whose trip count and indices are only known at run time (benchmarks/RESULTS.md, round 9, irr9 and
// unroll9). The same arithmetic either way, in the same order. STMT must not `continue` or `break`
// (a function returning the light's share, vec3(0) for none, added to a sum).
#ifdef SKIN_LIGHT_COUNT
#if SKIN_LIGHT_COUNT > MAX_LIGHTS || SKIN_LIGHT_COUNT > 8
#error "SKIN_LIGHT_COUNT: more lights than the light arrays hold or DERMIS_FOR_EACH_LIGHT writes out (8)"
#endif
#define DERMIS_LIGHT_STEP(K, STMT) { const int light_i = K; STMT }
#if SKIN_LIGHT_COUNT > 0
#define DERMIS_LIGHT_0(STMT) DERMIS_LIGHT_STEP(0, STMT)
#else
#define DERMIS_LIGHT_0(STMT)
#endif
#if SKIN_LIGHT_COUNT > 1
#define DERMIS_LIGHT_1(STMT) DERMIS_LIGHT_STEP(1, STMT)
#else
#define DERMIS_LIGHT_1(STMT)
#endif
#if SKIN_LIGHT_COUNT > 2
#define DERMIS_LIGHT_2(STMT) DERMIS_LIGHT_STEP(2, STMT)
#else
#define DERMIS_LIGHT_2(STMT)
#endif
#if SKIN_LIGHT_COUNT > 3
#define DERMIS_LIGHT_3(STMT) DERMIS_LIGHT_STEP(3, STMT)
#else
#define DERMIS_LIGHT_3(STMT)
#endif
#if SKIN_LIGHT_COUNT > 4
#define DERMIS_LIGHT_4(STMT) DERMIS_LIGHT_STEP(4, STMT)
#else
#define DERMIS_LIGHT_4(STMT)
#endif
#if SKIN_LIGHT_COUNT > 5
#define DERMIS_LIGHT_5(STMT) DERMIS_LIGHT_STEP(5, STMT)
#else
#define DERMIS_LIGHT_5(STMT)
#endif
#if SKIN_LIGHT_COUNT > 6
#define DERMIS_LIGHT_6(STMT) DERMIS_LIGHT_STEP(6, STMT)
#else
#define DERMIS_LIGHT_6(STMT)
#endif
#if SKIN_LIGHT_COUNT > 7
#define DERMIS_LIGHT_7(STMT) DERMIS_LIGHT_STEP(7, STMT)
#else
#define DERMIS_LIGHT_7(STMT)
#endif
#define DERMIS_FOR_EACH_LIGHT(STMT) DERMIS_LIGHT_0(STMT) DERMIS_LIGHT_1(STMT) DERMIS_LIGHT_2(STMT) DERMIS_LIGHT_3(STMT) \
    DERMIS_LIGHT_4(STMT) DERMIS_LIGHT_5(STMT) DERMIS_LIGHT_6(STMT) DERMIS_LIGHT_7(STMT)
#else
#define DERMIS_FOR_EACH_LIGHT(STMT) for (int light_i = 0; light_i < uLightCount; ++light_i) { STMT }
#endif
