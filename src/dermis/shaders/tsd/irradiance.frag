// Irradiance texture (d'Eon & Luebke 2007, 14.4.1 and 14.5.2), in UV space, linear float:
// E = sum_lights E_i max(N.L, 0) shadow_soft (1 - rho_s a(N.L, m) / pi) k(N.L) + ambient, times albedo^mix
// (k: the skin's directional albedo, common/directional_albedo.glsl).
// Alpha is coverage (1 on the mesh), for the normalised blurs that hide seams.
// With SKIN_SHARP_SHADOWS = 3 (scenes of at most 3 lights: dermis.techniques.tsd), f_sharp: coverage
// and the lights' sharp shadows (the specular's, common/skin_irradiance.glsl) for tsd/final.frag
// (tsd/sharp_shadow.glsl).
// With SKIN_EXITANT_LOCATION (tsd.py: its one bounce, dermis/geometry/interreflection.py) two more
// targets for that bounce, written here where the albedo map is read anyway: f_exitant, the light
// leaving the skin times pi, rho E = I_0 albedo^(1 - mix) (coverage 1; tsd/bounce_exitant.frag
// computes the same from I_0 in a mesh raster of its own), and f_albedo_mix = albedo^mix, the factor
// by which tsd/bounce_splat.frag adds the gathered bounce E_b to I_0 (instead of a second albedo map
// read and pow there). Where the framebuffer has no such attachments the writes are dropped.
#include "common/shadow.glsl"
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"
#include "common/environment.glsl"
#include "common/brdf.glsl"
#include "common/energy.glsl"
#include "common/skin_irradiance.glsl"
#include "common/directional_albedo.glsl"

uniform float uMix;
uniform float uDirectionalAlbedo;  // 1: the skin's directional albedo at entry (scene.directional_albedo), 0: Lambertian
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
in vec4 v_visibility;  // (ambient occlusion, visible fraction RGB): common/environment.glsl
layout(location = 0) out vec4 f_irradiance;
#ifdef SKIN_SHARP_SHADOWS
layout(location = 1) out vec4 f_sharp;
#endif
#ifdef SKIN_EXITANT_LOCATION
layout(location = SKIN_EXITANT_LOCATION) out vec4 f_exitant;
layout(location = SKIN_ALBEDO_MIX_LOCATION) out vec4 f_albedo_mix;
#endif

void main() {
    vec3 Ng = normalize(v_normal);
    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    float rho_s = specular_intensity(v_uv);
    float m = roughness_at(v_uv);
    vec3 albedo = albedo_at(v_uv);
    vec3 c = uDirectionalAlbedo * directional_c(albedo);
    // lights (each by the directional albedo's k(N.L)), soft shadows, ambient, energy
    vec3 E = skin_irradiance_directional(v_world, Ng, N, rho_s, m, v_visibility, c);
    vec3 albedo_mix = albedo_power(albedo, uMix);
    f_irradiance = vec4(E * albedo_mix, 1.0);
#ifdef SKIN_EXITANT_LOCATION
    f_exitant = vec4(f_irradiance.rgb * albedo_power(albedo, 1.0 - uMix), 1.0);
    f_albedo_mix = vec4(albedo_mix, 1.0);
#endif
#ifdef SKIN_SHARP_SHADOWS
    f_sharp = vec4(1.0, skin_sharp_shadow.xyz);
#endif
}
