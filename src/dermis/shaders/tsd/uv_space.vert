// Texture-space passes: the mesh is rasterised in its UV layout (d'Eon & Luebke 2007, 14.4.1):
// gl_Position = (uv_ts * 2 - 1, 0, 1), while lighting uses the world-space attributes and the
// material maps the asset's own UVs (v_uv).
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 3) in vec4 in_tangent;
layout(location = 5) in vec2 in_uv_ts;  // the texture-space UV set (the mesh's own when unique)
layout(location = 6) in vec4 in_visibility;  // (ambient occlusion, visible fraction RGB): geometry/visibility.py
layout(location = 7) in vec2 in_uv1;  // TEXCOORD_1 (maps whose texCoord is 1)
out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
out vec2 v_uv1;
out vec4 v_tangent;
out vec4 v_visibility;
#ifdef INTERREFLECTION
// tsd/bounce_splat.frag: the bounce irradiance gathered per vertex (tsd/bounce_gather.frag), vertex
// v at texel (v mod P, v div P); gl_VertexID is the index buffer's value, the vertex's number
uniform sampler2D uBounce;
uniform int uVerticesPerRow;
out vec3 v_bounce;
#endif
void main() {
#ifdef INTERREFLECTION
    v_bounce = texelFetch(uBounce, ivec2(gl_VertexID % uVerticesPerRow, gl_VertexID / uVerticesPerRow), 0).rgb;
#endif
    v_world = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    v_uv1 = in_uv1;
    v_tangent = in_tangent;
    v_visibility = in_visibility;
    gl_Position = vec4(in_uv_ts * 2.0 - 1.0, 0.0, 1.0);
}
