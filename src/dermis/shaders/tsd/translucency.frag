// Translucency through thin parts with translucent shadow maps (d'Eon & Luebke 2007, 14.5.3).
// For a texel on the side facing away from light i, the TSM gives the (u, v) where the light
// entered and the distance d (mm) it travelled through the skin. Because
// G(v, sqrt(r^2 + d^2)) = exp(-d^2 / 2v) G(v, r), the light transmitted by Gaussian k is the
// lit side's already-blurred irradiance I_k(uv_near) scaled by exp(-d^2 / 2 v_k); only the wide
// Gaussians (variance >= uTranslucencyMinVariance) are used, the narrow ones carry nothing
// through millimetres of tissue. Computed in texture space: view-independent, cached.
#include "common/shadow.glsl"
#include "tsd/gaussians.glsl"

uniform float uTranslucencyMinVariance;
uniform float uTranslucencyStrength;
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
out vec4 f_translucency;

void main() {
    vec3 Ng = normalize(v_normal);
    vec3 T = vec3(0.0);
    for (int i = 0; i < uLightCount; ++i) {
        if (uLightRadiance[i].w < 0.5) continue;  // no shadow map, no TSM
        vec3 L;
        light_incident(i, v_world, L);
        // facing away from the light; the ramp avoids a seam at the terminator
        float away = smoothstep(0.0, 0.25, -dot(Ng, L));
        if (away <= 0.0) continue;
        vec2 uv_near;
        float dist_near;
        if (!tsm_lookup(i, v_world, uv_near, dist_near)) continue;
        float d = max(light_distance_mm(i, v_world) - dist_near, 0.0);
        for (int k = 0; k < MAX_GAUSSIANS; ++k) {
            if (k >= uGaussianCount) break;
            if (uVariances[k] < uTranslucencyMinVariance) continue;
            T += away * uWeights[k] * exp(-d * d / (2.0 * uVariances[k])) * texture(uBlur[k], uv_near).rgb;
        }
    }
    f_translucency = vec4(T * uTranslucencyStrength, 1.0);
}
