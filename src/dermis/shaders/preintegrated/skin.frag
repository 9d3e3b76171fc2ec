// Pre-integrated skin (Penner & Borshukov 2011, GPU Pro 2 ch. II.1), in one mesh pass: the
// profile's scattering comes from lookup tables built at start-up (dermis/techniques/preintegrated.py),
//   diffuse = albedo / pi * (1 - rho_s a(N.V, m) / pi)
//             * [ k(N.V) ( sum_lights E_i D(N_c.L, curvature)_c P(shadow_soft, penumbra width)_c k(N.L)
//                                         (1 - rho_s a(N.L, m) / pi)
//                          + ambient(N_c) )
//                 + transmitted ]                                                  per channel c
//   specular = common/skin_specular.glsl (shared by every skin technique)
// N_c: the normal map filtered by channel c's profile, a mip level per Gaussian (Penner's blurred
// normals, red blurriest); D: light wrapped around a ring of the local curvature; P: the soft
// shadow's penumbra scattered with the profile (red reaches furthest into the shadow); k: the
// skin's directional albedo (common/directional_albedo.glsl; the ambient enters at k = 1, the light
// through thin parts leaves Lambertian, as in tsd).
#include "common/surface.glsl"
#include "common/noise.glsl"
#include "common/shadow.glsl"
#include "common/environment.glsl"
#include "common/energy.glsl"
#include "common/skin_specular.glsl"
#include "common/transmittance.glsl"
#include "common/directional_albedo.glsl"
#include "common/interreflection.glsl"

uniform sampler2D uDiffuseTable;   // D(N.L, curvature): s = N.L in [-1, 1], t = sqrt(curvature / max)
uniform sampler2D uPenumbraTable;  // P(shadow, width): s = shadow in [0, 1], t = log-spaced width
uniform float uCurvatureMaxPerMm;
uniform vec2 uPenumbraWidthRangeMm;
uniform float uCurvatureFromMesh;   // 1: the mesh's per-vertex curvature, 0: screen derivatives
uniform float uBlurredNormals;      // 1: per-channel blurred normals, 0: the detailed normal
uniform float uPenumbraScattering;  // 1: scatter the penumbra through its table, 0: plain PCF
uniform float uDirectionalAlbedo;   // 1: the skin's directional albedo (scene.directional_albedo), 0: Lambertian
uniform vec3 uCameraPos;
uniform float uPoreScaleMm;
uniform float uPoreStrength;
uniform int uOutputMode;  // OUTPUT_FULL, _DIFFUSE, _SPECULAR or _CURVATURE (1/mm; dermis.techniques.shared.OutputMode)
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
in vec4 v_visibility;  // (ambient occlusion, visible fraction RGB): common/environment.glsl
in vec2 v_uv_ts;  // texture-space UVs: the thickness bake
in float v_curvature;
out vec4 f_color;


// Texel-centre coordinate: f = 0 and 1 land on the first and last texels' centres.
vec2 table_coord(sampler2D table, vec2 f) {
    vec2 size = vec2(textureSize(table, 0));
    return (clamp(f, 0.0, 1.0) * (size - 1.0) + 0.5) / size;
}

// Penner's D per channel, each channel at its own N.L.
vec3 diffuse_lookup(vec3 ndl, float curvature) {
    float t = sqrt(clamp(curvature / uCurvatureMaxPerMm, 0.0, 1.0));
    return vec3(textureLod(uDiffuseTable, table_coord(uDiffuseTable, vec2(ndl.r * 0.5 + 0.5, t)), 0.0).r,
                textureLod(uDiffuseTable, table_coord(uDiffuseTable, vec2(ndl.g * 0.5 + 0.5, t)), 0.0).g,
                textureLod(uDiffuseTable, table_coord(uDiffuseTable, vec2(ndl.b * 0.5 + 0.5, t)), 0.0).b);
}

vec3 penumbra_lookup(float shadow, float width_mm) {
    float t = log(max(width_mm, 1e-6) / uPenumbraWidthRangeMm.x) / log(uPenumbraWidthRangeMm.y / uPenumbraWidthRangeMm.x);
    return textureLod(uPenumbraTable, table_coord(uPenumbraTable, vec2(shadow, t)), 0.0).rgb;
}

// Width (mm) of light i's penumbra on the surface at P: measured from the PCF taps' own gradient
// (common/shadow.glsl, shadow_soft_penumbra; no screen derivatives), bounded by the PCF filter's
// diameter, 2 (softness + 1) texels (the Poisson disc and each tap's bilinear 2x2), in world units
// from the light's projection (uv per world unit = |row 0| / 2w), projected on the surface: from
// that (an edge along the light's projected direction) to that / N.L (across it).
float penumbra_width_mm(int i, vec3 P, float ndl_geometric, float measured_mm) {
    mat4 M = uLightViewProj[i];
    float w = (M * vec4(P, 1.0)).w;
    float row0 = length(vec3(M[0][0], M[1][0], M[2][0]));
    float texel_world = uShadowParams[i].w * 2.0 * abs(w) / max(row0, 1e-12);
    float pcf_mm = 2.0 * (uShadowParams[i].x + 1.0) * texel_world * uMmPerUnit;
    return clamp(measured_mm, pcf_mm, pcf_mm / max(ndl_geometric, 0.2));
}

void main() {
    vec3 Ngeo = normalize(v_normal);
    vec3 P_mm = v_world * uMmPerUnit;
    // curvature (1/mm): the mesh's, or Penner's length(fwidth(N)) / length(fwidth(P)). Every screen
    // derivative here is the fine one (per pixel, not per 2x2 quad): GLSL leaves plain dFdx / fwidth
    // to the implementation, which picks coarse or fine per GPU.
    float curvature_derivatives = length(fwidthFine(Ngeo)) / max(length(fwidthFine(P_mm)), 1e-9);
    float curvature = uCurvatureFromMesh > 0.5 ? abs(v_curvature) : curvature_derivatives;
    // the normal map's texels per mm (square root of the area ratio of a pixel's footprint)
    vec2 tex = vec2(textureSize(uNormalMap, 0));
    vec2 nuv = normal_map_uv(v_uv);  // the normal map's own coordinates (its UV set and transform)
    vec2 duvx = dFdxFine(nuv) * tex, duvy = dFdyFine(nuv) * tex;
    float area_uv = abs(duvx.x * duvy.y - duvx.y * duvy.x);
    float area_mm = length(cross(dFdxFine(P_mm), dFdyFine(P_mm)));  // a pixel's footprint, mm^2
    float texels_per_mm = sqrt(area_uv / max(area_mm, 1e-12));

    vec3 N = perturb_normal(v_normal, v_tangent, v_uv);
    // blurred normals: channel c's normal is the normal map filtered by channel c's own profile,
    // sum_k w_ck (the map filtered by Gaussian k), each Gaussian the mip level whose box has its
    // standard deviation (level L averages 2^L texels, a box of standard deviation 2^L / sqrt(12)),
    // never finer than the pixel's own footprint: the level of the OpenGL 4.5 spec's (8.14)
    // isotropic formula, log2 of the longer of the two texel-space derivatives (textureQueryLod is
    // allowed to approximate it, and GPUs do). Not one level at the profile's rms radius: that is
    // set by the wide tail (red 1.18 mm) and wiped out the third of red's weight within 0.25 mm,
    // so red lost all the bumps that green and blue kept; at a terminator, where N.L magnifies the
    // bumps, that drew red/green grain (issue 12, the back-lit head behind the ear).
    float footprint_lod = 0.5 * log2(max(max(dot(duvx, duvx), dot(duvy, duvy)), 1e-12));
    mat3 n_profile = mat3(0.0);  // columns: red, green, blue; tangent-space sums
    for (int k = 0; k < uGaussianCount; ++k) {
        float box_texels = sqrt(uVariances[k]) * texels_per_mm * 3.4641016;  // sqrt(12) sigma_k
        float lod_k = max(log2(max(box_texels, 1.0)) * uBlurredNormals, footprint_lod);
        vec3 m_k = textureLod(uNormalMap, nuv, lod_k).xyz * 2.0 - 1.0;
        n_profile += mat3(m_k * uWeights[k].r, m_k * uWeights[k].g, m_k * uWeights[k].b);
    }
    vec3 N_red = tangent_to_world(v_normal, v_tangent, n_profile[0]);
    vec3 N_green = tangent_to_world(v_normal, v_tangent, n_profile[1]);
    vec3 N_blue = tangent_to_world(v_normal, v_tangent, n_profile[2]);

    vec3 V = normalize(uCameraPos - v_world);
    float m = roughness_at(v_uv);
    float rho_s = specular_intensity(v_uv);
    vec3 Ns = pore_normal(N, P_mm, uPoreScaleMm, uPoreStrength);
    float ndv = clamp(dot(Ns, V), 0.0, 1.0);

    vec3 albedo = albedo_at(v_uv);
    vec3 c = uDirectionalAlbedo * directional_c(albedo);
    vec3 E = vec3(0.0);
    for (int i = 0; i < uLightCount; ++i) {
        vec3 L;
        vec3 Ei = light_incident(i, v_world, L);
        vec3 D = diffuse_lookup(vec3(dot(N_red, L), dot(N_green, L), dot(N_blue, L)), curvature);
        bool lit = max(D.r, max(D.g, D.b)) > 0.0;
        if (!lit) continue;
        float width_mm;
        float s = shadow_soft_penumbra(i, v_world, Ngeo, width_mm);
        vec3 S = vec3(s);
        if (uPenumbraScattering > 0.5 && s > 0.0 && s < 1.0)
            S = penumbra_lookup(s, penumbra_width_mm(i, v_world, dot(Ngeo, L), width_mm));
        // k(N.L) outside the table, on each light's contribution: D integrates the profile over the
        // ring of the local curvature, where the entry cosine runs around N.L; k could go inside
        // that integral only with the albedo as a third axis (c depends on it, per texel). k is linear
        // in mu with |c| <= 0.18, so taking it at the centre's N.L is exact on a flat surface and
        // off by c times the ring's profile-weighted spread of the cosine on a curved one. N.L is
        // the detailed normal's (the energy term's, tsd's); where the ring wraps light past the
        // terminator (N.L <= 0) k is the grazing one, k(0), which is where that light entered.
        float ndl = clamp(dot(N, L), 0.0, 1.0);
        E += Ei * D * S * energy_transmitted(rho_s, ndl, m) * directional_factor(c, ndl);
    }
    vec3 ambient = vec3(environment_irradiance_occluded(N_red, Ngeo, v_visibility).r,
                        environment_irradiance_occluded(N_green, Ngeo, v_visibility).g,
                        environment_irradiance_occluded(N_blue, Ngeo, v_visibility).b);
    E += ambient * energy_transmitted(rho_s, 0.5, m);
#ifdef DERMIS_INTERREFLECTION
    E += bounce_irradiance();  // one bounce: as smooth as the profile's reach, no table (common/interreflection.glsl)
#endif
    // the exit's k(N.V) on the reflected light; the light through a thin part leaves Lambertian
    E = E * directional_factor(c, ndv) + transmitted_irradiance(v_world, Ngeo, v_uv_ts);

    vec3 diffuse = E * albedo * INV_PI * energy_transmitted(rho_s, ndv, m);
    vec3 spec = skin_specular_radiance(v_world, Ngeo, Ns, V, m, rho_s, uSpecularTables, v_visibility);
    vec3 color = uOutputMode == OUTPUT_DIFFUSE ? diffuse : uOutputMode == OUTPUT_SPECULAR ? spec
                : uOutputMode == OUTPUT_CURVATURE ? vec3(curvature) : diffuse + spec;
    f_color = vec4(color, 1.0);
}
