// Bench floor: write the interpolated attributes, nothing else.
in vec3 v_attr;
out vec4 f_color;
void main() {
    f_color = vec4(v_attr * 1e-3, 1.0);
}
