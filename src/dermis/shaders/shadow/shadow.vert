// Shadow / translucent-shadow-map pass: renders the mesh from light i into its atlas tile.
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 5) in vec2 in_uv_ts;  // the TSM stores texture-space UVs (tsd looks its blurs up there)
uniform mat4 uViewProj;
out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_uv = in_uv_ts;
    gl_Position = uViewProj * vec4(in_position, 1.0);
}
