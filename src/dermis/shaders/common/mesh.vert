// Screen-space mesh pass shared by the techniques: world-space attributes for lighting.
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 3) in vec4 in_tangent;
uniform mat4 uViewProj;
out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
out vec4 v_tangent;
void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    v_tangent = in_tangent;
    gl_Position = uViewProj * vec4(in_position, 1.0);
}
