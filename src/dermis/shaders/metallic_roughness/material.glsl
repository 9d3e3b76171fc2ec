// A glTF 2.0 metallic-roughness material's inputs (glTF 2.0 spec 3.9.2-3.9.5), each map read
// through its own UV set and KHR_texture_transform (map_uv, common/surface.glsl). A material
// without a map gets a 1x1 white one (flat normal for the normal map), so the factors apply alone.
// Uniforms are set by dermis/gl/surfaces.py; units of the samplers: techniques/shared.py.
#include "common/surface.glsl"

uniform vec4 uBaseColorFactor;       // linear RGBA
uniform sampler2D uBaseColorMap;     // RGBA, sRGB decoded to linear on load
uniform mat3 uBaseColorUV;
uniform int uBaseColorSet;
uniform float uMetallicFactor;
uniform float uRoughnessFactor;
uniform sampler2D uMetallicRoughnessMap;  // G = roughness, B = metallic (linear)
uniform mat3 uMetallicRoughnessUV;
uniform int uMetallicRoughnessSet;
uniform sampler2D uOcclusionMap;     // R = ambient occlusion (linear)
uniform mat3 uOcclusionUV;
uniform int uOcclusionSet;
uniform float uOcclusionStrength;
uniform vec3 uEmissiveFactor;        // linear RGB radiance
uniform sampler2D uEmissiveMap;      // sRGB decoded to linear on load
uniform mat3 uEmissiveUV;
uniform int uEmissiveSet;
uniform float uAlphaCutoff;          // alphaMode MASK: the cutoff; OPAQUE: -1 (nothing is cut)

// Base colour and coverage alpha (glTF 2.0 3.9.2: factor x texture); MASK discards below the
// cutoff (3.9.4), in the shading and in the shadow pass alike.
vec4 mr_base_color(vec2 uv) {
    vec4 c = uBaseColorFactor * texture(uBaseColorMap, map_uv(uBaseColorUV, uBaseColorSet, uv));
    if (c.a < uAlphaCutoff) discard;
    return c;
}

// (metallic, roughness) in [0, 1] (3.9.2: factor x the map's B and G channels).
vec2 mr_metallic_roughness(vec2 uv) {
    vec4 t = texture(uMetallicRoughnessMap, map_uv(uMetallicRoughnessUV, uMetallicRoughnessSet, uv));
    return clamp(vec2(uMetallicFactor * t.b, uRoughnessFactor * t.g), 0.0, 1.0);
}

// 3.9.3: occlusion = 1 + strength (map - 1); it scales ambient (environment) light only.
float mr_occlusion(vec2 uv) {
    return 1.0 + uOcclusionStrength * (texture(uOcclusionMap, map_uv(uOcclusionUV, uOcclusionSet, uv)).r - 1.0);
}

vec3 mr_emission(vec2 uv) {
    return uEmissiveFactor * texture(uEmissiveMap, map_uv(uEmissiveUV, uEmissiveSet, uv)).rgb;
}
