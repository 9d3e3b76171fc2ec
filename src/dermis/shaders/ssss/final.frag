// Separable SSS, pass 4: the mesh drawn into the frame's (multisampled) target with the scattered
// light of the pixel, then the surface's own terms, as in tsd's final pass:
//   diffuse = scattered * albedo^(1 - mix) / pi * (1 - rho_s a(N.V, m) / pi)
//   specular = common/skin_specular.glsl, added AFTER the blur (Jimenez et al. 2009, sec. 3)
//   + T_geo / pi * (1 - rho_s a(N.V, m) / pi): the baked subsurface transfer of thin, curled parts
//     (common/subsurface_transfer.glsl, gathered from rho E: light leaving the skin), after the blur
//     as tsd adds it after its blurs; + its view term (subsurface_transfer_view: the transfer along this
//     fragment's view less its cosine views' mean, round 22)
// Drawing the mesh again (instead of a full-screen composite) keeps the depth buffer and the
// multisampled silhouettes of the other techniques. A fragment whose depth does not match what
// pass 1 saw at its pixel (an MSAA edge sample of another surface) takes the scattered light of
// the 3x3 neighbour nearest in depth.
// first: the varyings on the fragment's own triangle (before any code that reads them)
#include "common/mesh_varyings.glsl"
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"
#include "common/noise.glsl"
#include "common/energy.glsl"
#include "common/skin_specular.glsl"
#include "common/subsurface_transfer.glsl"
// TEXEL: uScattered is NEAREST, CLAMP_TO_EDGE (ssss.py): the border texel for a pixel past it
#include "common/texel.glsl"

uniform sampler2D uScattered;   // rgb scattered light, a = view depth mm (0: none)
uniform vec4 uViewZ;
uniform float uMix;
uniform float uPoreScaleMm;
uniform float uPoreStrength;
uniform int uOutputMode;  // OUTPUT_FULL, OUTPUT_DIFFUSE or OUTPUT_SPECULAR (dermis.techniques.shared.OutputMode)
out vec4 f_color;

const float SAME_SURFACE_MM = 1.0;

vec3 scattered_here(float depth_mm) {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = TEXEL(uScattered, p);
    if (c.a > 0.0 && abs(c.a - depth_mm) < SAME_SURFACE_MM) return c.rgb;
    vec3 best = c.rgb;
    float best_dz = c.a > 0.0 ? abs(c.a - depth_mm) : 1e30;
    for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x) {
            vec4 t = TEXEL(uScattered, p + ivec2(x, y));
            float dz = abs(t.a - depth_mm);
            if (t.a > 0.0 && dz < best_dz) {
                best_dz = dz;
                best = t.rgb;
            }
        }
    return best;
}

void main() {
    load_mesh_varyings();
    vec3 Ng = normalize(v_normal);
    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    vec3 V = normalize(uCameraPos - v_world);
    float m = roughness_at(v_uv);
    float rho_s = specular_intensity(v_uv);
    vec3 Ns = pore_normal(N, v_world * uMmPerUnit, uPoreScaleMm, uPoreStrength);
    float ndv = clamp(dot(Ns, V), 0.0, 1.0);

    float depth_mm = max(-dot(uViewZ, vec4(v_world, 1.0)) * uMmPerUnit, 1e-3);
    vec3 albedo = albedo_at(v_uv);
    vec3 diffuse = (scattered_here(depth_mm) * albedo_power(albedo, 1.0 - uMix) + subsurface_transfer(v_uv_ts)
                    + subsurface_transfer_view(v_uv_ts, V, Ng))
                   * INV_PI * energy_transmitted(rho_s, ndv, m);
    vec3 spec = skin_specular_radiance(v_world, Ng, Ns, V, m, rho_s, uSpecularTables, v_visibility,
                                       v_blocked_sh0, v_blocked_sh1, v_blocked_sh2);

    vec3 color = uOutputMode == OUTPUT_DIFFUSE ? diffuse : uOutputMode == OUTPUT_SPECULAR ? spec : diffuse + spec;
    f_color = vec4(color, 1.0);
}
