// dermis/shaders/common/brdf.glsl: specular BRDF terms shared by every technique (include, never copy).
//
// Skin: Kelemen & Szirmay-Kalos 2001 with a Beckmann distribution, as in d'Eon & Luebke 2007
// (GPU Gems 3 ch. 14, section 14.3). Baseline: normalised Blinn-Phong. The numpy reference, the
// table layouts and the energy convention are documented in dermis/specular.py; the two tables are
// uploaded side by side in ONE texture by dermis.gl.tables.upload_specular_tables (R32F, linear,
// clamp-to-edge; uniform uSpecularTables), at the texel rectangles DERMIS_BECKMANN_RECT and
// DERMIS_RHO_DT_RECT (x0, y0, cols, rows) of common/constants.glsl (dermis.specular.TABLE_ATLAS).
//
// Units: all vectors are unit length and in one space; results are per unit light radiance. The
// skin terms are d'Eon's as written, with no 1/pi: callers divide by pi to get physical radiance
// (the convention is stated once, in dermis/techniques/shared.py).
//
// Configuration (#define before including, or through dermis.gl.shaders defines):
//   DERMIS_BECKMANN_ANALYTIC  beckmann() evaluates the closed form instead of the table.
//   DERMIS_SKIN_F0            Schlick F0 of skin (default dermis.specular.SKIN_F0).
// The tables' roughness range DERMIS_SPECULAR_M_MIN / _M_MAX is dermis.specular.M_MIN / M_MAX,
// generated into common/constants.glsl.
#include "common/constants.glsl"

uniform sampler2D uSpecularTables;  // the Beckmann and rho_dt tables (dermis.gl.tables)

// Beckmann 1963 as in d'Eon & Luebke 2007 (GPU Gems 3, 14.3, PHBeckmann), no 1/pi:
// P = exp(-tan^2(alpha) / m^2) / (m^2 cos^4(alpha)); integral P (N.H) dw_H = pi. Reference only.
float beckmann_analytic(float ndoth, float m) {
    // clamp keeps 1/c^4 finite in fp32 (1e-16); at c = 1e-4 the exponential is already 0
    float c = max(ndoth, 1e-4);
    float c2 = c * c;
    float tan2 = (1.0 - c) * (1.0 + c) / c2;  // (1 - c^2) / c^2 without cancelling c^2 first
    float m2 = m * m;
    return exp(-tan2 / m2) / (m2 * c2 * c2);
}

// Texel-centre coordinate into a dermis specular table (dermis/specular.py) kept in the texel
// rectangle rect = (x0, y0, cols, rows) of the texture: x in [0, 1] along s, roughness along t as
// y = log(m / M_MIN) / log(M_MAX / M_MIN); value i/(cols-1) sits on the centre of the rectangle's
// column i, and the clamp keeps the bilinear footprint inside the rectangle.
vec2 specular_table_coord(sampler2D table, vec4 rect, float x, float m) {
    vec2 size = vec2(textureSize(table, 0));
    float mc = clamp(m, DERMIS_SPECULAR_M_MIN, DERMIS_SPECULAR_M_MAX);
    float y = log(mc / DERMIS_SPECULAR_M_MIN) / log(DERMIS_SPECULAR_M_MAX / DERMIS_SPECULAR_M_MIN);
    vec2 f = clamp(vec2(x, y), 0.0, 1.0);
    return (rect.xy + f * (rect.zw - 1.0) + 0.5) / size;
}

// d'Eon & Luebke 2007, section 14.3: Beckmann P(N.H, m) precomputed into a texture (float here, so P is
// stored as is). The table's s axis is sqrt(1 - N.H): the lobe is then about a Gaussian of width m/2
// and linear filtering stays within 3e-4 of the peak 1/m^2 and within 0.7% of P where P > 1% of the
// peak, for m in [0.1, 1] (tests/test_specular.py).
float beckmann_lookup(sampler2D beckmannTex, float ndoth, float m) {
    float x = sqrt(clamp(1.0 - ndoth, 0.0, 1.0));
    return textureLod(beckmannTex, specular_table_coord(beckmannTex, DERMIS_BECKMANN_RECT, x, m), 0.0).r;
}

// Beckmann distribution (d'Eon & Luebke 2007, 14.3): table by default, closed form with
// DERMIS_BECKMANN_ANALYTIC. Swapping the variant is one #define (Filament's dispatch style).
float beckmann(sampler2D beckmannTex, float ndoth, float m) {
#ifdef DERMIS_BECKMANN_ANALYTIC
    return beckmann_analytic(ndoth, m);
#else
    return beckmann_lookup(beckmannTex, ndoth, m);
#endif
}

// Schlick 1994, "An Inexpensive BRDF Model for Physically-based Rendering": F = F0 + (1 - F0)(1 - V.H)^5.
float fresnel_schlick(float vdoth, float f0) {
    float f = 1.0 - clamp(vdoth, 0.0, 1.0);
    float f2 = f * f;
    return f0 + (1.0 - f0) * (f2 * f2 * f);
}

// Kelemen & Szirmay-Kalos 2001 via d'Eon & Luebke 2007 (GPU Gems 3, 14.3, KS_Skin_Specular):
// N.L * rho_s * P(H) * F(V.H) / dot(h, h), h = L + V UNnormalised, H = normalize(h); 0 unless
// N.L > 0 and N.V > 0. Multiply by light radiance and a SHARP shadow term.
float ks_skin_specular(vec3 N, vec3 L, vec3 V, float m, float rho_s, sampler2D beckmannTex) {
    float ndotl = dot(N, L);
    float ndotv = dot(N, V);
    vec3 h = L + V;
    float hh = dot(h, h);
    // N.L > 0 and N.V > 0 imply hh > 0; the 1e-12 only guards against fp32 rounding at grazing
    if (ndotl <= 0.0 || ndotv <= 0.0 || hh <= 1e-12) {
        return 0.0;
    }
    vec3 H = h * inversesqrt(hh);
    float P = beckmann(beckmannTex, dot(N, H), m);
    float F = fresnel_schlick(dot(V, H), DERMIS_SKIN_F0);
    return ndotl * rho_s * max(P * F / hh, 0.0);
}

// d'Eon & Luebke 2007, section 14.3: specular albedo a(cos, m) = integral of ks_skin_specular (rho_s = 1)
// over the hemisphere, from the table (s axis sqrt(cos)). Energy left for diffuse: 1 - rho_s * a / pi,
// with cosTheta = N.L for light entering the skin and N.V for light leaving it.
float rho_dt_lookup(sampler2D rhoDtTex, float cosTheta, float m) {
    float x = sqrt(clamp(cosTheta, 0.0, 1.0));
    return textureLod(rhoDtTex, specular_table_coord(rhoDtTex, DERMIS_RHO_DT_RECT, x, m), 0.0).r;
}

// Blinn 1977, "Models of Light Reflection for Computer Synthesized Pictures", with the energy
// normalisation (n + 8) / (8 pi) (Akenine-Moller, Haines & Hoffman 2008, Real-Time Rendering 3rd
// ed., section 7.6): ks (n + 8) / (8 pi) (N.H)^n N.L; 0 unless N.L > 0 and N.V > 0. Baseline only.
// A physical BRDF already (it keeps its 1/pi), so it is used as is beside a diffuse of albedo E / pi.
float blinn_phong_specular(vec3 N, vec3 L, vec3 V, float shininess, float ks) {
    float ndotl = dot(N, L);
    float ndotv = dot(N, V);
    if (ndotl <= 0.0 || ndotv <= 0.0) {
        return 0.0;
    }
    vec3 H = normalize(L + V);
    float ndoth = max(dot(N, H), 0.0);
    return ks * (shininess + 8.0) * (0.125 * INV_PI) * pow(ndoth, shininess) * ndotl;
}
