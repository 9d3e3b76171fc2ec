// Seam fill (dermis.geometry.seams, dermis.gl.seam_fill): one point per gutter texel beside a UV seam,
// carrying the UV of the same surface point in the neighbouring chart.
in vec2 in_texel;   // the gutter texel (column, row) of the target texture, row 0 = v 0
in vec2 in_target;  // UV of the same surface point in the neighbouring chart
uniform vec2 uSize; // texels per side of the target texture
out vec2 v_target;
void main() {
    v_target = in_target;
    gl_Position = vec4((in_texel + 0.5) / uSize * 2.0 - 1.0, 0.0, 1.0);
    gl_PointSize = 1.0;
}
