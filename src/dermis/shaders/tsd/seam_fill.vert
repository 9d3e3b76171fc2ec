// Seam fill (dermis.geometry.seams, dermis.gl.seam_fill): rectangles of 4 x 4 cells of the target texture that hold
// the step's gutter texels beside a UV seam, as quads (clip-space corners).
in vec2 in_position;
void main() {
    gl_Position = vec4(in_position, 0.0, 1.0);
}
