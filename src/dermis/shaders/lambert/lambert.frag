// Baseline: Lambert diffuse + normalised Blinn-Phong specular, soft (PCF) shadows.
// The "hard, dry" look every skin technique must visibly beat. Radiance is physical:
// diffuse = albedo / pi * E * N.L (Lambert 1760); specular from common/brdf.glsl.
// first: the varyings on the fragment's own triangle (before any code that reads them)
#include "common/mesh_varyings.glsl"
#include "common/shadow.glsl"
#include "common/surface.glsl"
#include "common/environment.glsl"
#include "common/brdf.glsl"
#include "common/interreflection.glsl"

out vec4 f_color;

// Light i's diffuse and specular radiance at v_world (0 where it does not reach the surface). The
// diffuse takes the normal map's shadowing by the smooth surface (bump_shadowing, common/shadow.glsl:
// none below the interpolated normal's horizon); the Ng.L > -0.05 gate is the specular's.
vec3 lambert_light(int i, vec3 Ng, vec3 N, vec3 V, vec3 albedo, float shininess, float ks) {
    vec3 L;
    vec3 E = light_incident(i, v_world, L);
    float ndl = dot(N, L);
    if (ndl <= 0.0 || dot(Ng, L) <= -0.05) return vec3(0.0);
    float s = shadow_soft(i, v_world, Ng);
    return E * s * (albedo * INV_PI * ndl * bump_shadowing(Ng, N, L) + vec3(blinn_phong_specular(N, L, V, shininess, ks)));
}

void main() {
    load_mesh_varyings();
    vec3 Ng = normalize(v_normal);
    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    vec3 V = normalize(uCameraPos - v_world);
    vec3 albedo = albedo_at(v_uv);
    float rho_s = specular_intensity(v_uv);
    // Beckmann m -> Blinn-Phong exponent with the same highlight width (Walter et al. 2007, eq. 30)
    float m = roughness_at(v_uv);
    float shininess = max(2.0 / (m * m) - 2.0, 1.0);
    // Like-for-like with the skin specular: ks chosen so the normalised lobe's peak at normal
    // incidence equals KS_Skin_Specular's, rho_s F0 / (4 m^2 pi) (d'Eon 2007, 14.3), i.e.
    // ks (n + 8) / (8 pi) = rho_s F0 / (4 m^2 pi). No Fresnel: the baseline's highlight is flat.
    float ks = rho_s * 0.028 * 2.0 / (m * m * (shininess + 8.0));
    vec3 color = albedo * INV_PI * environment_irradiance_occluded(N, Ng, v_visibility);
#ifdef DERMIS_INTERREFLECTION
    color += albedo * INV_PI * bounce_irradiance();  // the bounce light, every order (common/interreflection.glsl)
#endif
    // the environment's specular (common/environment.glsl) times the lobe's albedo, taken at
    // normal incidence for every view: ks n (n + 8) / ((n + 2)(n + 4)) (the integral of the
    // normalised Blinn-Phong lobe for V = N, its cut at N.L = 0 neglected; baseline approximation)
    float ndv = clamp(dot(N, V), 0.0, 1.0);
    float albedo_bp = ks * shininess * (shininess + 8.0) / ((shininess + 2.0) * (shininess + 4.0));
    color += albedo_bp * environment_specular(specular_dominant_direction(N, reflect(-V, N), m), m)
             * specular_occlusion_sh(reflect(-V, N), Ng, v_blocked_sh0, v_blocked_sh1, v_blocked_sh2);
    DERMIS_FOR_EACH_LIGHT(color += lambert_light(light_i, Ng, N, V, albedo, shininess, ks);)  // common/lights.glsl
    f_color = vec4(color, 1.0);
}
