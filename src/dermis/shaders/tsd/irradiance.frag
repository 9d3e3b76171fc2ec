// Irradiance texture (d'Eon & Luebke 2007, 14.4.1 and 14.5.2), in UV space, linear float:
// E = sum_lights E_i max(N.L, 0) shadow_soft (1 - rho_s a(N.L, m) / pi) + ambient, times albedo^mix.
// Alpha is coverage (1 on the mesh), for the normalised blurs that hide seams.
// f_sharp: coverage and each light's sharp shadow (the specular's, common/skin_irradiance.glsl),
// for tsd/final.frag (tsd/sharp_shadow.glsl): flat channel 0 coverage, 1 + i light i, four per target.
#define SKIN_SHARP_SHADOWS
#include "common/shadow.glsl"
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"
#include "common/environment.glsl"
#include "common/brdf.glsl"
#include "common/energy.glsl"
#include "common/skin_irradiance.glsl"
#include "tsd/sharp_shadow.glsl"

uniform float uMix;
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
in vec4 v_visibility;  // (ambient occlusion, bent normal)
layout(location = 0) out vec4 f_irradiance;
layout(location = 1) out vec4 f_sharp[SHARP_SHADOW_TARGETS];

void main() {
    vec3 Ng = normalize(v_normal);
    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    float rho_s = specular_intensity(v_uv);
    float m = roughness_at(v_uv);
    vec3 E = skin_irradiance(v_world, Ng, N, rho_s, m, v_visibility);  // lights, soft shadows, ambient, energy
    vec3 albedo = albedo_at(v_uv);
    f_irradiance = vec4(E * albedo_power(albedo, uMix), 1.0);
    for (int t = 0; t < SHARP_SHADOW_TARGETS; ++t) {
        vec4 o;
        for (int c = 0; c < 4; ++c) {
            int j = 4 * t + c;  // flat channel: 0 coverage, 1 + i light i
            o[c] = j == 0 ? 1.0 : j <= MAX_LIGHTS ? skin_sharp_shadow[j - 1] : 0.0;
        }
        f_sharp[t] = o;
    }
}
