// Shadow pass: renders the skin mesh from light i into its atlas tile, depth only (no fragment
// shader, no colour attachment: the least a shadow map costs, as bench/depth_only.vert measures).
layout(location = 0) in vec3 in_position;
uniform mat4 uViewProj;
void main() {
    gl_Position = uViewProj * vec4(in_position, 1.0);
}
