// Bench floor: a depth-only raster of the mesh (no colour attachment), the least a shadow map costs.
layout(location = 0) in vec3 in_position;
uniform mat4 uViewProj;
void main() {
    gl_Position = uViewProj * vec4(in_position, 1.0);
}
