// Bench floor: the mesh rasterised in its UV layout with the same vertex attributes as the
// texture-space passes, and a constant colour: the least any texture-space pass can cost.
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
out vec3 v_attr;
void main() {
    v_attr = in_position + in_normal;
    gl_Position = vec4(in_uv * 2.0 - 1.0, 0.0, 1.0);
}
