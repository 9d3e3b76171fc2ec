// Translucency through thin parts with translucent shadow maps (d'Eon & Luebke 2007, 14.5.3).
// For a texel on the side facing away from light i, the TSM gives the (u, v) where the light
// entered and the thickness t (mm) of tissue it crossed along the light (common/shadow.glsl,
// tsm_thickness_mm). Because G(v, sqrt(r^2 + t^2)) = exp(-t^2 / 2v) G(v, r),
// the light that Gaussian k carries THROUGH the tissue is the lit side's already-blurred
// irradiance I_k(uv_near) scaled by exp(-t^2 / 2 v_k).
//
// The blur chain has already carried the light of the entry point A = uv_near to this texel B
// ALONG the surface, with Gaussian k's kernel exp(-g^2 / 2 v_k) G(v_k, r) for a surface distance
// g between A and B. Light reaches B from A by the shorter path, and G falls with distance, so the
// translucency adds only what the path through the tissue gives beyond it:
//   T_k = w_k I_k(uv_near) max(0, exp(-t^2 / 2 v_k) - exp(-g^2 / 2 v_k)).
// Without it, texels just past the terminator of thick parts (nose, eyelids, lips, jaw), where
// the light's entry point is their own neighbour (t and g -> 0), counted that light twice: thin
// bright lines along every shadow edge (example head: max 1.24 against a 99.9th percentile of
// 0.23). Across an ear A and B are far apart on the surface (or in other UV islands) and the
// whole transmitted light remains. g is measured in the texture: |uv_near - uv| in texels over
// the stretch (texels per mm), exact for a flat layout, longer across a UV seam (no correction).
// Only the wide Gaussians (variance >= uTranslucencyMinVariance) are used, the narrow ones carry
// nothing through millimetres of tissue. Computed in texture space: view-independent, cached.
#include "common/shadow.glsl"
#include "tsd/gaussians.glsl"

uniform float uTranslucencyMinVariance;
uniform float uTranslucencyStrength;
uniform sampler2D uStretch;  // texels per mm along u, v (tsd/stretch.frag)
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
        float t = tsm_thickness_mm(i, v_world, uv_near);
        if (t < 0.0) continue;
        vec2 stretch = max(texture(uStretch, v_uv).xy, vec2(1e-6));
        vec2 texels = (uv_near - v_uv) * vec2(textureSize(uStretch, 0));
        float g = length(texels / stretch);  // mm along the surface from A to B
        for (int k = 0; k < MAX_GAUSSIANS; ++k) {
            if (k >= uGaussianCount) break;
            if (uVariances[k] < uTranslucencyMinVariance) continue;
            float excess = max(exp(-t * t / (2.0 * uVariances[k])) - exp(-g * g / (2.0 * uVariances[k])), 0.0);
            T += away * excess * uWeights[k] * texture(uBlur[k], uv_near).rgb;
        }
    }
    f_translucency = vec4(T * uTranslucencyStrength, 1.0);
}
