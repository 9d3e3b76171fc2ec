// dermis/shaders/common/metallic_roughness.glsl: the BRDF of glTF 2.0's metallic-roughness
// material (glTF 2.0 specification, Appendix B "BRDF Implementation"), for every surface that is
// not skin. The numpy twin used by the tests is tests/test_metallic_roughness.py (mr_brdf).
//
// Units: unit vectors in one space; results are BRDF values (1/sr): multiply by the irradiance a
// light brings at normal incidence and by N.L for radiance. Physical, like the skin shaders
// (dermis/techniques/shared.py): a white Lambertian surface under irradiance E leaves E / pi.
#include "common/constants.glsl"

// Trowbridge-Reitz / GGX normal distribution (glTF 2.0 B.3.2, "Specular BRDF"; Walter et al.
// 2007, eq. 33): D = alpha^2 chi+(N.H) / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2), alpha = roughness^2.
float mr_distribution_ggx(float ndoth, float alpha) {
    if (ndoth <= 0.0) return 0.0;
    float a2 = alpha * alpha;
    float d = ndoth * ndoth * (a2 - 1.0) + 1.0;
    return a2 * INV_PI / max(d * d, 1e-12);
}

// Height-correlated Smith visibility V = G2 / (4 |N.L| |N.V|) for GGX (Heitz 2014, "Understanding
// the Masking-Shadowing Function", eq. 99; the form of glTF 2.0 B.3.2's reference implementation,
// glTF-Sample-Viewer's V_GGX): V = 0.5 / (N.L sqrt(N.V^2 (1 - a^2) + a^2) + N.V sqrt(N.L^2 (1 - a^2) + a^2)).
float mr_visibility_smith_ggx(float ndotl, float ndotv, float alpha) {
    float a2 = alpha * alpha;
    float gv = ndotl * sqrt(ndotv * ndotv * (1.0 - a2) + a2);
    float gl = ndotv * sqrt(ndotl * ndotl * (1.0 - a2) + a2);
    float s = gv + gl;
    return s > 0.0 ? 0.5 / s : 0.0;
}

// Schlick's Fresnel (glTF 2.0 B.3.4, "Fresnel"; Schlick 1994): F = F0 + (1 - F0) (1 - |V.H|)^5.
vec3 mr_fresnel_schlick(vec3 f0, float vdoth) {
    float f = 1.0 - clamp(abs(vdoth), 0.0, 1.0);
    float f2 = f * f;
    return f0 + (1.0 - f0) * (f2 * f2 * f);
}

// F0 of the metallic-roughness model (glTF 2.0 B.3.5, "Metal BRDF and Dielectric BRDF"): 0.04 for
// the dielectric (ior 1.5), the base colour for the metal, mixed by metallic.
vec3 mr_f0(vec3 base_color, float metallic) {
    return mix(vec3(0.04), base_color, metallic);
}

// The whole BRDF (glTF 2.0 B.3.5, its "fresnel_mix" / "conductor_fresnel" combined as in B.3.6's
// implementation): f = (1 - F) (1 - metallic) baseColor / pi  +  F D V, returned as its diffuse
// and specular terms. 0 unless N.L > 0 and N.V > 0.
void mr_brdf_terms(vec3 N, vec3 L, vec3 V, vec3 base_color, float metallic, float roughness,
                   out vec3 diffuse, out vec3 specular) {
    diffuse = specular = vec3(0.0);
    float ndotl = dot(N, L);
    float ndotv = dot(N, V);
    if (ndotl <= 0.0 || ndotv <= 0.0) return;
    vec3 H = normalize(L + V);
    float alpha = roughness * roughness;
    vec3 F = mr_fresnel_schlick(mr_f0(base_color, metallic), dot(V, H));
    diffuse = (1.0 - F) * (1.0 - metallic) * base_color * INV_PI;
    specular = F * mr_distribution_ggx(dot(N, H), alpha) * mr_visibility_smith_ggx(ndotl, ndotv, alpha);
}

vec3 mr_brdf(vec3 N, vec3 L, vec3 V, vec3 base_color, float metallic, float roughness) {
    vec3 d, s;
    mr_brdf_terms(N, L, V, base_color, metallic, roughness, d, s);
    return d + s;
}

// The directional albedo of F D V over the hemisphere, F0 * A + B (the split-sum "environment BRDF"
// of Karis 2013, "Real Shading in Unreal Engine 4"), in the analytic fit of Karis 2014 ("Physically
// Based Shading on Mobile", EnvBRDFApprox, after Lazarov 2013): weights the environment's specular.
vec3 mr_environment_brdf(vec3 f0, float ndotv, float roughness) {
    const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022);
    const vec4 c1 = vec4(1.0, 0.0425, 1.04, -0.04);
    vec4 r = roughness * c0 + c1;
    float a004 = min(r.x * r.x, exp2(-9.28 * ndotv)) * r.x + r.y;
    vec2 ab = vec2(-1.04, 1.04) * a004 + r.zw;
    return f0 * ab.x + ab.y;
}
