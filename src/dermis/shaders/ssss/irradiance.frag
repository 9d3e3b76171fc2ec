// Separable SSS, pass 1 (Jimenez et al. 2009, 2015): the light that enters the skin, in screen
// space, into a non-multisampled float target of the frame's size:
//   rgb = (E k(N.V) + T) * albedo^mix   E from common/skin_irradiance.glsl (lights, each by the
//                                skin's directional albedo k(N.L), soft shadows, ambient, energy
//                                conservation), T the light transmitted through thin parts
//                                (common/transmittance.glsl, Jimenez et al. 2010)
// k(mu) = 1 + c(A) (2/3 - mu): common/directional_albedo.glsl (dermis.profiles.directional_albedo).
// The exit's k(N.V) is applied HERE, to the reflected part only, because the blurs mix E and T into
// one scattered light and the light through a thin part leaves Lambertian (as in tsd/final.frag);
// it is the N.V of the pixel where the light enters rather than where it leaves, which differs by
// k's change across the kernel: at most c (<= 0.18) times the change of N.V over a few mm.
//   a   = view-space depth in mm (> 0; the target is cleared to 0 = no surface)
// The blur passes scale their kernels by this depth and compare depths to follow the surface.
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"
#include "common/skin_irradiance.glsl"
#include "common/transmittance.glsl"
#include "common/directional_albedo.glsl"
#include "common/interreflection.glsl"

uniform float uMix;
uniform vec4 uViewZ;  // third row of the view matrix: view-space z = dot(uViewZ, (P, 1)), < 0 in front
uniform mat3 uViewRotation;  // the view matrix's rotation: normals to view space
uniform vec3 uCameraPos;
uniform float uDirectionalAlbedo;  // 1: the skin's directional albedo (scene.directional_albedo), 0: Lambertian
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
in vec4 v_visibility;  // (ambient occlusion, visible fraction RGB): common/environment.glsl
in vec2 v_uv_ts;  // texture-space UVs: the thickness bake
layout(location = 0) out vec4 f_irradiance;
layout(location = 1) out vec4 f_view_normal;  // the blurs' tissue-path test (ssss/kernel.glsl)

void main() {
    vec3 Ng = normalize(v_normal);
    // the thickness bake's uv per scene unit on this triangle (the far-face shadow's taps: common/transmittance.glsl)
    mat3x2 uv_per_unit = texture_space_per_unit(dFdxFine(v_world), dFdyFine(v_world), dFdxFine(v_uv_ts), dFdyFine(v_uv_ts));
    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    float rho_s = specular_intensity(v_uv);
    float m = roughness_at(v_uv);
    vec3 albedo = albedo_at(v_uv);
    vec3 c = uDirectionalAlbedo * directional_c(albedo);
    float ndv = clamp(dot(N, normalize(uCameraPos - v_world)), 0.0, 1.0);
    vec3 E_in = skin_irradiance_directional(v_world, Ng, N, rho_s, m, v_visibility, c);
#ifdef DERMIS_INTERREFLECTION
    E_in += bounce_irradiance();  // one bounce, before the blurs, which scatter it (common/interreflection.glsl)
#endif
    vec3 E = E_in * directional_factor(c, ndv) + transmitted_irradiance(v_world, Ng, v_uv_ts, uv_per_unit);
    float depth_mm = max(-dot(uViewZ, vec4(v_world, 1.0)) * uMmPerUnit, 1e-3);
    f_irradiance = vec4(E * albedo_power(albedo, uMix), depth_mm);
    // the FACET's normal (the plane of the triangle, from the screen derivatives of the position:
    // exact, v_world is linear on a triangle), oriented as the interpolated one: the depth these
    // pixels write lies on it, so two pixels of one facet see each other in its plane and a bend
    // between facets is the angle between their normals (the interpolated normal lags a coarse
    // mesh's facets by up to 15 degrees at the side view's inner eye corner, which the tissue-path
    // test, ssss/kernel.glsl, read as air between neighbours of one facet)
    vec3 Nf = cross(dFdx(v_world), dFdy(v_world));
    float nf = length(Nf);
    Nf = nf > 0.0 ? Nf / nf : Ng;
    if (dot(Nf, Ng) < 0.0) Nf = -Nf;
    f_view_normal = vec4(normalize(uViewRotation * Nf), 1.0);
}
