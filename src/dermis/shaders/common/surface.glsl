// Surface attributes shared by techniques: tangent-space normal mapping and material lookups.
#include "common/constants.glsl"
uniform sampler2D uAlbedoMap;     // linear RGB (sRGB decoded on load)
uniform vec3 uAlbedoScale;        // 1, or the skin colour of a physical profile over the map's mean
uniform sampler2D uNormalMap;     // tangent space, OpenGL convention (+y = +v), encoded n*0.5+0.5
uniform sampler2D uSpecularMap;   // intensity in [0,1]
uniform float uNormalStrength;
uniform float uRhoS;              // Kelemen/Szirmay-Kalos specular intensity (d'Eon 2007: 0.18)
uniform float uRoughness;         // Beckmann m (d'Eon 2007: 0.3), used where there is no map
uniform sampler2D uRoughnessMap;  // optional: Beckmann m per texel (linear data)
uniform float uHasRoughnessMap;   // 1 when uRoughnessMap holds a map
uniform vec2 uSpecMapBiasScale;   // rho_s(x) = rho_s * (bias + scale * specMap(x))

// Per-map addressing (glTF texCoord + KHR_texture_transform; dermis.scene.model.Texture): each map
// reads UV set 0 (the ``uv`` passed in: the mesh's TEXCOORD_0, v_uv) or set 1 (v_uv1, written by
// common/mesh.vert and tsd/uv_space.vert) through its own 3x3 affine transform of (u, v, 1), v up.
#ifndef DERMIS_MESH_VARYINGS  // else declared there (common/mesh_varyings.glsl)
in vec2 v_uv1;
#endif
uniform mat3 uAlbedoUV, uNormalUV, uSpecularUV, uRoughnessUV;
uniform int uAlbedoSet, uNormalSet, uSpecularSet, uRoughnessSet;

vec2 map_uv(mat3 T, int set, vec2 uv) {
    return (T * vec3(set == 1 ? v_uv1 : uv, 1.0)).xy;
}
vec2 normal_map_uv(vec2 uv) { return map_uv(uNormalUV, uNormalSet, uv); }

// MikkTSpace tangent frame: B = w * cross(N, T) (columns t, b, n), N and T interpolated.
mat3 tangent_frame(vec3 N, vec4 T) {
    vec3 n = normalize(N);
    vec3 t = normalize(T.xyz - n * dot(n, T.xyz));
    return mat3(t, T.w * cross(n, t), n);
}

// The map's normal m (decoded) taken to world space, its slope scaled by uNormalStrength.
vec3 tangent_to_world(vec3 N, vec4 T, vec3 m) {
    m.xy *= uNormalStrength;
    return normalize(tangent_frame(N, T) * m);
}

vec3 perturb_normal(vec3 N, vec4 T, vec2 uv) {
    return tangent_to_world(N, T, texture(uNormalMap, normal_map_uv(uv)).xyz * 2.0 - 1.0);
}

// The normal map read at a given mip level: the normal averaged over 2^lod texels, a blurred
// normal (pre-integrated skin reads one per colour channel, as wide as that channel scatters).
vec3 perturb_normal_lod(vec3 N, vec4 T, vec2 uv, float lod) {
    return tangent_to_world(N, T, textureLod(uNormalMap, normal_map_uv(uv), lod).xyz * 2.0 - 1.0);
}

float specular_intensity(vec2 uv) {
    return uRhoS * (uSpecMapBiasScale.x + uSpecMapBiasScale.y * texture(uSpecularMap, map_uv(uSpecularUV, uSpecularSet, uv)).r);
}

// Beckmann roughness m at uv: the map when the scene has one, else the scene's constant
// (Weyrich et al. 2006 measured m per face region: 0.2-0.5). Clamped to the tables' range.
float roughness_at(vec2 uv) {
    float m = uHasRoughnessMap > 0.5 ? texture(uRoughnessMap, map_uv(uRoughnessUV, uRoughnessSet, uv)).r : uRoughness;
    return clamp(m, DERMIS_SPECULAR_M_MIN, DERMIS_SPECULAR_M_MAX);
}

// Diffuse albedo at uv (linear). With a physical skin profile the total diffuse reflectance comes
// from the profile, and the map keeps only its relative variation (uAlbedoScale).
vec3 albedo_at(vec2 uv) {
    return max(texture(uAlbedoMap, map_uv(uAlbedoUV, uAlbedoSet, uv)).rgb * uAlbedoScale, vec3(0.0));
}
