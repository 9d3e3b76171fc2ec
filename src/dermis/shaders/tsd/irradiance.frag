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
#ifndef SKIN_BOUNCE_FROM_INPUTS  // that pass reads no map (and its vertex stage has no v_uv1)
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"
#include "common/directional_albedo.glsl"
#endif
#include "common/environment.glsl"
#include "common/brdf.glsl"
#include "common/energy.glsl"
#include "common/skin_irradiance.glsl"

#ifndef SKIN_BOUNCE_FROM_INPUTS
uniform float uMix;
uniform float uDirectionalAlbedo;  // 1: the skin's directional albedo at entry (scene.directional_albedo), 0: Lambertian
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
in vec4 v_visibility;  // (ambient occlusion, visible fraction RGB): common/environment.glsl
#else
// The shared bounce's rho E (dermis.gl.interreflection.SharedBounce) in two passes: SKIN_BOUNCE_INPUTS
// (tsd/uv_space.vert, the mesh in its layout) writes what depends on no light, once per content:
// P and rho_s, N and m, Ng (0 off the mesh: coverage), the directional albedo's c, albedo^mix and
// the ambient E_a (skin_ambient), as 32-bit floats, the values this pass would compute; then per
// lighting change SKIN_BOUNCE_FROM_INPUTS (common/fullscreen.vert over the same texels) reads them
// back and adds the lights: (E_lights + E_a) albedo^mix, the same sums in the same order. tsd's own
// irradiance pass is drawn the same way (dermis.gl.irradiance_inputs, "Round 16, branch perf16" in
// benchmarks/RESULTS.md), with its sharp shadows (SKIN_SHARP_SHADOWS) and rho E (SKIN_EXITANT_LOCATION,
// from a sixth input, SKIN_INPUTS_ALBEDO_REST: albedo^(1 - mix)). On llvmpipe
// the mesh raster of ~18k triangles of ~14 texels each shades many half-covered blocks and fetches 4
// filtered maps per texel; the full-screen pass shades each texel once with 5 texel reads.
// The reads are TEXEL (common/texel.glsl: textureLod at the texel's centre; the inputs are NEAREST,
// dermis.gl.irradiance_inputs, and drawn at this pass's size), the same floats as texelFetch and
// ~5 ms less of tsd's ~125 ms pass on the head at 1024^2 (benchmarks/results/round-24.md, irr24).
#include "common/texel.glsl"
uniform sampler2D uBounceInputs[5];
#endif
#if defined(SKIN_BOUNCE_INPUTS)
layout(location = 0) out vec4 f_P_rho_s;
layout(location = 1) out vec4 f_N_m;
layout(location = 2) out vec4 f_Ng_ambient_b;
layout(location = 3) out vec4 f_c_ambient_r;
layout(location = 4) out vec4 f_albedo_mix_ambient_g;
#else
layout(location = 0) out vec4 f_irradiance;
#endif
#if defined(SKIN_BOUNCE_INPUTS) && defined(SKIN_INPUTS_ALBEDO_REST)
// tsd's inputs (dermis.gl.irradiance_inputs): albedo^(1 - mix), the factor by which the light pass
// turns I_0 into rho E for the bounce (f_exitant below)
layout(location = 5) out vec4 f_albedo_rest;
#endif
#if defined(SKIN_BOUNCE_FROM_INPUTS) && defined(SKIN_EXITANT_LOCATION)
uniform sampler2D uAlbedoRest;  // SKIN_INPUTS_ALBEDO_REST's target
#endif
#if defined(SKIN_SHARP_SHADOWS) && !defined(SKIN_BOUNCE_INPUTS)
layout(location = 1) out vec4 f_sharp;
#endif
#if defined(SKIN_EXITANT_LOCATION) && !defined(SKIN_BOUNCE_INPUTS)
layout(location = SKIN_EXITANT_LOCATION) out vec4 f_exitant;
#endif
#if defined(SKIN_ALBEDO_MIX_LOCATION) && !defined(SKIN_BOUNCE_INPUTS) && !defined(SKIN_BOUNCE_FROM_INPUTS)
layout(location = SKIN_ALBEDO_MIX_LOCATION) out vec4 f_albedo_mix;
#endif

#if defined(SKIN_BOUNCE_INPUTS)
void main() {
    vec3 Ng = normalize(v_normal);
    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    float rho_s = specular_intensity(v_uv);
    float m = roughness_at(v_uv);
    vec3 albedo = albedo_at(v_uv);
    vec3 c = uDirectionalAlbedo * directional_c(albedo);
    vec3 Ea = skin_ambient(N, Ng, rho_s, m, v_visibility);
    f_P_rho_s = vec4(v_world, rho_s);
    f_N_m = vec4(N, m);
    f_Ng_ambient_b = vec4(Ng, Ea.b);
    f_c_ambient_r = vec4(c, Ea.r);
    f_albedo_mix_ambient_g = vec4(albedo_power(albedo, uMix), Ea.g);
#ifdef SKIN_INPUTS_ALBEDO_REST
    f_albedo_rest = vec4(albedo_power(albedo, 1.0 - uMix), 1.0);
#endif
}
#elif defined(SKIN_BOUNCE_FROM_INPUTS)
void main() {
    ivec2 t = ivec2(gl_FragCoord.xy);
    vec4 ng = TEXEL(uBounceInputs[2], t);
    if (ng.xyz == vec3(0.0)) {  // off the mesh: as the raster's clear
        f_irradiance = vec4(0.0);
#ifdef SKIN_SHARP_SHADOWS
        f_sharp = vec4(0.0);
#endif
#ifdef SKIN_EXITANT_LOCATION
        f_exitant = vec4(0.0);
#endif
        return;
    }
    vec4 p = TEXEL(uBounceInputs[0], t), n = TEXEL(uBounceInputs[1], t);
    vec4 c = TEXEL(uBounceInputs[3], t), am = TEXEL(uBounceInputs[4], t);
    vec3 E = skin_lights_directional(p.xyz, ng.xyz, n.xyz, p.w, n.w, c.rgb);
    E += vec3(c.a, am.a, ng.a);
    f_irradiance = vec4(E * am.rgb, 1.0);
    // tsd's outputs of its one-raster pass (below), but albedo^mix: a light-independent input that
    // tsd/bounce_splat.frag reads from uBounceInputs[4] itself (dermis.techniques.tsd)
#ifdef SKIN_SHARP_SHADOWS
    f_sharp = vec4(1.0, skin_sharp_shadow.xyz);
#endif
#ifdef SKIN_EXITANT_LOCATION
    f_exitant = vec4(f_irradiance.rgb * TEXEL(uAlbedoRest, t).rgb, 1.0);
#endif
}
#else
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
#endif
