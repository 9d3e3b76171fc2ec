// Bench floor: the mesh rasterised on screen (depth-tested), carrying normal and uv.
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
uniform mat4 uViewProj;
out vec3 v_attr;
void main() {
    v_attr = in_normal + vec3(in_uv, 0.0);
    gl_Position = uViewProj * vec4(in_position, 1.0);
}
