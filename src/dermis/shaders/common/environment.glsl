// Ambient light from the environment as 9 spherical-harmonic coefficients of its IRRADIANCE
// (Ramamoorthi & Hanrahan 2001, "An Efficient Representation for Irradiance Environment Maps",
// eq. 13): E(n) = sum_lm A_l L_lm Y_lm(n), with the A_l folded into uEnvSH on the CPU.
#include "common/constants.glsl"
uniform vec3 uEnvSH[9];
uniform sampler3D uEnvSpecular;  // the prefiltered environment (dermis.gl.environment)

// The real SH basis Y_lm, l <= 2, at the unit direction n, in dermis.environment.sh9_basis's order
// (its numpy twin): the one basis the irradiance below and specular_occlusion_sh evaluate.
void sh9_basis(vec3 n, out float y[9]) {
    y[0] = 0.282095;
    y[1] = 0.488603 * n.y; y[2] = 0.488603 * n.z; y[3] = 0.488603 * n.x;
    y[4] = 1.092548 * n.x * n.y; y[5] = 1.092548 * n.y * n.z; y[6] = 0.315392 * (3.0 * n.z * n.z - 1.0);
    y[7] = 1.092548 * n.x * n.z; y[8] = 0.546274 * (n.x * n.x - n.y * n.y);
}

vec3 environment_irradiance(vec3 n) {
    float y[9];
    sh9_basis(n, y);
    vec3 e = vec3(0.0);
    for (int i = 0; i < 9; ++i) e += uEnvSH[i] * y[i];
    return max(e, vec3(0.0));
}

// Occluded environment light (dermis/geometry/visibility.py, whose numpy twins these are).
// vis: the interpolated per-vertex visibility attribute, (A, r): A the cosine-weighted ambient
// occlusion (Zhukov et al. 1998; Landis 2002), r (per channel) the fraction of the SH irradiance
// at the vertex normal that the environment still sends past the mesh, E_occluded / E_sh, with the
// blocked light integrated over the bake's rays against the full-resolution image (r = A for a
// constant environment). With environment occlusion off vis = (1, 1, 1, 1): the unoccluded terms.
// Ng is unused (the visible fraction was baked about the vertex normal); kept for the callers.
vec3 environment_irradiance_occluded(vec3 N, vec3 Ng, vec4 vis) {
    // vis is a fraction of the sky; interpolated past its triangle (an MSAA edge fragment's pixel
    // centre: GLSL 4.50, "Interpolation Qualifiers") it can leave [0, 1] and gave negative radiance
    return clamp(vis.yzw, 0.0, 1.0) * environment_irradiance(N);
}

// Directional specular occlusion from the per-vertex L2 spherical harmonics of the directions the
// mesh blocks (dermis.geometry.visibility.VertexVisibility.blocked_sh, projected on the CPU from the
// visibility bake's own rays; the numpy twin is dermis.geometry.visibility.specular_occlusion_sh):
// the visible share of the lobe about the mirror direction R is 1 - B(R) / H(R), B the blocked
// directions' SH (b0..b2: coefficients 0-2, 3-5, 6-8), H the open hemisphere's about the bake's
// normal N in closed form, 1/2 + 3/4 (R.N) (its band 2 vanishes; Sloan 2008, "Stupid Spherical
// Harmonics Tricks"): two equally truncated projections, exactly 1 at an open vertex. Against a ray
// cast of the lobe on the head (benchmarks/RESULTS.md, round 15): mean |error| 0.053 of the blocked
// share, 0.071 at N.V <= 0.2, where Jimenez et al. 2016's cone about the bent normal (rounds 14-15)
// erred by 0.094 and 0.150 (+0.13 at grazing: a ring round the horizon, which a grazing lobe crosses).
// Lagarde & de Rousiers 2014's listing 26 (before round 14) sees how much sky, not where: it let the
// studio reflect on the nose's flank through the cheek (round 14).
const float BLOCKED_SH_MIN_HEMISPHERE = 0.05;  // R far below the bake normal's horizon (a bent normal map)
float specular_occlusion_sh(vec3 R, vec3 N, vec3 b0, vec3 b1, vec3 b2) {
    float y[9];
    sh9_basis(R, y);
    float b = dot(b0, vec3(y[0], y[1], y[2])) + dot(b1, vec3(y[3], y[4], y[5])) + dot(b2, vec3(y[6], y[7], y[8]));
    float h = max(0.5 + 0.75 * dot(R, N), BLOCKED_SH_MIN_HEMISPHERE);
    return 1.0 - clamp(b / h, 0.0, 1.0);
}

// The environment's specular radiance along R for a lobe of Beckmann roughness m: the equirect
// prefiltered with the skin's KSK / Beckmann lobe (dermis/prefiltered_environment.py) in LAYERS
// maps, layer k for m_k = M_MIN (M_MAX / M_MIN)^(k / (LAYERS - 1)), so the third coordinate is the
// specular tables' roughness coordinate y(m) at layer centres (linear filtering: linear in log m).
// The split sum (Karis 2013): multiply by the lobe's directional albedo (skin: rho_s a(N.V, m) / pi
// of the rho_dt table). Same equirect convention as the SH (dermis.environment): u = 0.5 +
// atan2(x, -z) / 2 pi, v = acos(y) / pi, row 0 up. A constant environment is one texel.
// GGX callers (alpha as m): the layers are Beckmann lobes, of the same width at the peak but
// without GGX's long tail (Walter et al. 2007, sec. 5.2); see dermis/prefiltered_environment.py.
vec3 environment_specular(vec3 R, float m) {
    float u = 0.5 + (abs(R.x) + abs(R.z) > 0.0 ? atan(R.x, -R.z) : 0.0) * (0.5 * INV_PI);
    float v = acos(clamp(R.y, -1.0, 1.0)) * INV_PI;
    float mc = clamp(m, DERMIS_SPECULAR_M_MIN, DERMIS_SPECULAR_M_MAX);
    float y = log(mc / DERMIS_SPECULAR_M_MIN) / log(DERMIS_SPECULAR_M_MAX / DERMIS_SPECULAR_M_MIN);
    float layers = float(DERMIS_ENV_SPECULAR_LAYERS);
    return textureLod(uEnvSpecular, vec3(u, v, (y * (layers - 1.0) + 0.5) / layers), 0.0).rgb;
}

// The direction to look the prefiltered environment up in: R bent towards N as the lobe's mass
// moves off the mirror direction at rougher and more grazing reflection (Lagarde & de Rousiers
// 2014, "Moving Frostbite to PBR", sec. 4.9.3, listing 22, fitted for GGX alpha; used here with
// alpha = Beckmann m). Against the Monte Carlo integral of the KSK lobe on a sphere (m = 0.3,
// tests/test_environment_specular.py) it halves the split sum's bias at N.V in [0.4, 0.8].
// Radiance arriving from the environment around R for a glossy lobe of GGX roughness alpha
// (alpha = perceptual roughness^2; glTF metallic-roughness surfaces): the prefiltered environment
// at m = alpha (see environment_specular: Beckmann layers, GGX's long tail not included).
vec3 environment_specular_radiance(vec3 R, float alpha) {
    return environment_specular(R, alpha);
}

vec3 specular_dominant_direction(vec3 N, vec3 R, float m) {
    float s = clamp(1.0 - m, 0.0, 1.0);
    return normalize(mix(N, R, s * (sqrt(s) + m)));
}

// The split sum's environment term for the SKIN's KSK / Beckmann lobe (common/skin_specular.glsl):
// looked up along the mirror direction R itself with the lobe NARROWED as the view grazes,
// m_eff = m (N.V)^0.8. Why: the prefiltered layers hold the lobe for a view along the normal; at
// grazing view the reflected lobe is squeezed across the plane of incidence (a half-vector spread
// d maps to a reflected spread of 2 d (V.H) there: ~N.V at grazing; Karis 2013's stretched
// reflections) and clipped by the horizon inside it, so its radiance-weighted average is that of a
// NARROWER lobe about R, not of a lobe bent towards N. Against the brute-force integral of the KSK
// BRDF on random normals and views in four environments (studio.exr, the tests' smooth HDR, two
// random lobe sets; m = 0.3 and 0.45; benchmarks/RESULTS.md, "Eyelids, ssss cost and environment
// specular"), mean relative error over N.V in [0.4, 1]: 17 % with Lagarde's bent direction (the
// GGX fit above), 13 % along R, 6.0 % along R with m (N.V)^0.8 (exponents 0.4 / 0.6 / 1.0: 8.2 /
// 6.7 / 6.2 %). A constant environment is unchanged (every layer is the constant).
// The exponent: DERMIS_SKIN_ENV_GRAZING_EXPONENT (dermis.prefiltered_environment, whose numpy twin
// skin_environment_specular this is).
vec3 skin_environment_specular(vec3 N, vec3 V, float m) {
    float ndv = clamp(dot(N, V), 1e-4, 1.0);
    return environment_specular(reflect(-V, N), m * pow(ndv, DERMIS_SKIN_ENV_GRAZING_EXPONENT));
}
