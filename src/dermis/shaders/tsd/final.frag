// Final pass of texture-space diffusion (d'Eon & Luebke 2007, 14.4.4 and 14.5), in screen space:
// diffuse = (sum_k w_k I_k(uv) k(N.V) + translucency) * albedo^(1 - mix) / pi * (1 - rho_s a(N.V, m) / pi)
// (k: the skin's directional albedo, common/directional_albedo.glsl; k(N.L) weighted the irradiance).
// specular = sum_lights E_i * sharp shadow * KS_Skin_Specular / pi, on pore-detailed normals.
// Radiance is physical (d'Eon's BRDFs carry no 1/pi; dermis divides both terms by pi).
#include "common/shadow.glsl"
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"
#include "common/environment.glsl"
#include "common/brdf.glsl"
#include "common/noise.glsl"
#include "common/energy.glsl"
#include "common/directional_albedo.glsl"
#ifdef SHARP_SHADOW_READ  // at most STORED_SHARP_SHADOWS lights: their shadows from the irradiance pass
#include "tsd/sharp_shadow.glsl"
#define SPECULAR_SHADOW(i, P, Ng) stored_sharp_shadow(i)
#endif
#include "common/skin_specular.glsl"
#include "tsd/gaussians.glsl"
#include "tsd/triangle_uv.glsl"

uniform sampler2D uTranslucency;
uniform float uMix;
uniform float uDirectionalAlbedo;  // 1: the skin's directional albedo at exit (scene.directional_albedo), 0: Lambertian
uniform float uPoreScaleMm;
uniform float uPoreStrength;
uniform vec3 uCameraPos;
uniform int uOutputMode;  // OUTPUT_FULL, OUTPUT_DIFFUSE or OUTPUT_SPECULAR (dermis.techniques.shared.OutputMode)
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec2 v_uv_ts;  // texture-space UVs: tsd's own textures; v_uv: the material maps
in vec4 v_tangent;
in vec4 v_visibility;  // (ambient occlusion, visible fraction RGB): common/environment.glsl
in vec3 v_blocked_sh0;  // the L2 SH of the directions the mesh blocks: the specular occlusion
in vec3 v_blocked_sh1;
in vec3 v_blocked_sh2;
out vec4 f_color;


void main() {
    vec3 Ng = normalize(v_normal);
    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    vec3 V = normalize(uCameraPos - v_world);
    float m = roughness_at(v_uv);
    float rho_s = specular_intensity(v_uv);
    vec3 Ns = pore_normal(N, v_world * uMmPerUnit, uPoreScaleMm, uPoreStrength);
    float ndv = clamp(dot(Ns, V), 0.0, 1.0);

    // tsd's own textures at a point of this triangle (an edge sample's pixel-centre UV can lie
    // texels off it, on lit skin elsewhere: tsd/triangle_uv.glsl)
    vec2 uv_ts = uv_on_triangle(v_uv_ts, gl_PrimitiveID);

    vec3 albedo = albedo_at(v_uv);
    // k(N.V) is the half-space's REFLECTION (dermis.profiles.directional_albedo): the light that
    // entered on this side; the light through a thin part (translucency) is left Lambertian
    vec3 E = diffuse_irradiance(uv_ts) * directional_factor(uDirectionalAlbedo * directional_c(albedo), ndv)
           + texture(uTranslucency, uv_ts).rgb;
    vec3 diffuse = E * albedo_power(albedo, 1.0 - uMix) * INV_PI * energy_transmitted(rho_s, ndv, m);

#ifdef SHARP_SHADOW_READ
    load_sharp_shadows(uv_ts);
#endif
    vec3 spec = skin_specular_radiance(v_world, Ng, Ns, V, m, rho_s, uSpecularTables, v_visibility,
                                       v_blocked_sh0, v_blocked_sh1, v_blocked_sh2);

    vec3 color = uOutputMode == OUTPUT_DIFFUSE ? diffuse : uOutputMode == OUTPUT_SPECULAR ? spec : diffuse + spec;
    f_color = vec4(color, 1.0);
}
