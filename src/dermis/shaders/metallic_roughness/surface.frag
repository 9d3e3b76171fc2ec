// Non-skin surfaces (eyes, teeth, hair cards, props): glTF 2.0's metallic-roughness BRDF
// (common/metallic_roughness.glsl) under the scene's lights, shadowed through the same shadow
// atlas as the skin, plus the environment (SH irradiance for the diffuse, the shared environment
// specular function for the glossy part) scaled by the material's occlusion, plus emission.
// No scattering: drawn by every technique after its skin passes, with depth testing.
#include "common/shadow.glsl"
#include "common/environment.glsl"
#include "common/metallic_roughness.glsl"
#include "metallic_roughness/material.glsl"

uniform vec3 uCameraPos;
uniform int uOutputMode;  // OUTPUT_FULL / _DIFFUSE / _SPECULAR (anything else: black)
// the smallest roughness shaded: GGX's D at alpha -> 0 is a delta a pixel cannot resolve
const float MIN_ROUGHNESS = 0.03;
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
out vec4 f_color;

void main() {
    vec4 base = mr_base_color(v_uv);
    // doubleSided (glTF 2.0 3.9.6): a back face is lit with its normal reversed; single-sided
    // materials' back faces are culled (dermis/gl/surfaces.py)
    vec3 Ng = normalize(gl_FrontFacing ? v_normal : -v_normal);
    vec3 N = perturb_normal(Ng, v_tangent, v_uv);  // uNormalStrength = normalTexture.scale
    vec3 V = normalize(uCameraPos - v_world);
    vec2 mr = mr_metallic_roughness(v_uv);
    float metallic = mr.x, roughness = max(mr.y, MIN_ROUGHNESS);
    vec3 c_diff = (1.0 - metallic) * base.rgb;  // the ambient's diffuse colour
    vec3 f0 = mr_f0(base.rgb, metallic);
    vec3 diffuse = vec3(0.0), specular = vec3(0.0);
    for (int i = 0; i < uLightCount; ++i) {
        vec3 L;
        vec3 E = light_incident(i, v_world, L);
        float ndl = dot(N, L);
        if (ndl <= 0.0 || dot(Ng, L) <= -0.05) continue;
        vec3 fd, fs;
        mr_brdf_terms(N, L, V, base.rgb, metallic, roughness, fd, fs);
        float s = shadow_soft(i, v_world, Ng);
        diffuse += E * s * ndl * fd;
        specular += E * s * ndl * fs;
    }
    float ao = mr_occlusion(v_uv);
    float ndv = clamp(dot(N, V), 0.0, 1.0);
    diffuse += ao * c_diff * INV_PI * environment_irradiance(N);
    specular += ao * environment_specular_radiance(reflect(-V, N), roughness * roughness)
                * mr_environment_brdf(f0, ndv, roughness);
    vec3 emitted = mr_emission(v_uv);
    vec3 color = uOutputMode == OUTPUT_FULL ? diffuse + specular + emitted
               : uOutputMode == OUTPUT_DIFFUSE ? diffuse + emitted
               : uOutputMode == OUTPUT_SPECULAR ? specular : vec3(0.0);
    f_color = vec4(color, 1.0);
}
