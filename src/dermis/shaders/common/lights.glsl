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

// Direction to the light (unit) and the irradiance it brings at normal incidence, at point P.
vec3 light_incident(int i, vec3 P, out vec3 L) {
    int type = int(uLightPosType[i].w + 0.5);
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
