// Screen-space mesh pass shared by the techniques: world-space attributes for lighting.
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 3) in vec4 in_tangent;
layout(location = 5) in vec2 in_uv_ts;  // texture-space UV set (tsd's textures); in_uv: material maps
layout(location = 6) in vec4 in_visibility;  // (ambient occlusion, visible fraction RGB): geometry/visibility.py
layout(location = 8) in vec3 in_blocked_sh0;  // the L2 SH of the directions the mesh blocks (geometry/visibility.py
layout(location = 9) in vec3 in_blocked_sh1;  // VertexVisibility.blocked_sh, coefficients 0-2, 3-5, 6-8): the
layout(location = 10) in vec3 in_blocked_sh2;  // specular occlusion (common/environment.glsl)
layout(location = 7) in vec2 in_uv1;  // TEXCOORD_1 (maps whose texCoord is 1; zeros when absent)
#ifdef DERMIS_VERTEX_CURVATURE
layout(location = 4) in float in_curvature;  // a technique's own per-vertex scalar (preintegrated: 1/mm)
out float v_curvature;
#endif
#ifdef DERMIS_INTERREFLECTION
// the one-bounce irradiance E_b per mesh vertex (dermis.gl.interreflection.SharedBounce), vertex v at
// texel (v mod P, v div P); gl_VertexID is the index buffer's value, the vertex's number
uniform sampler2D uBounce;
uniform int uVerticesPerRow;
out vec3 v_bounce;
#endif
uniform mat4 uViewProj;
out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
out vec2 v_uv1;
out vec4 v_tangent;
out vec2 v_uv_ts;
out vec4 v_visibility;
out vec3 v_blocked_sh0;
out vec3 v_blocked_sh1;
out vec3 v_blocked_sh2;
// The position again for an edge pixel's fragment (common/mesh_varyings.glsl): over the clip w, with
// 1/w, interpolated linearly in screen space at a covered sample (noperspective centroid); the fragment
// divides (Heckbert & Moreton 1991, "Interpolation for polygon texture mapping and shading": p/w and 1/w
// are affine in screen space, so their ratio is the perspective-correct position at any point of the
// triangle). Why not plain `centroid`: llvmpipe's perspective-correct centroid values of a sliver came
// out farther off it than the pixel centre's (round 12: 5-9 texels; round 13: barycentrics down to
// -228), its noperspective centroid ones within 0.004 of the triangle (round 13, speck13).
noperspective centroid out vec4 c_world_w;  // (position, 1) / w
void main() {
    v_uv_ts = in_uv_ts;
    v_visibility = in_visibility;
    v_blocked_sh0 = in_blocked_sh0;
    v_blocked_sh1 = in_blocked_sh1;
    v_blocked_sh2 = in_blocked_sh2;
    v_world = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    v_uv1 = in_uv1;
    v_tangent = in_tangent;
#ifdef DERMIS_VERTEX_CURVATURE
    v_curvature = in_curvature;
#endif
#ifdef DERMIS_INTERREFLECTION
    v_bounce = texelFetch(uBounce, ivec2(gl_VertexID % uVerticesPerRow, gl_VertexID / uVerticesPerRow), 0).rgb;
#endif
    gl_Position = uViewProj * vec4(in_position, 1.0);
    c_world_w = vec4(in_position, 1.0) / gl_Position.w;
}
