// Seam fill: the gutter texel takes the blur step's input at the same surface point in the
// neighbouring chart (bilinear: the target lies between texel centres), premultiplied as the chain's
// data (tsd/blur.frag), so the next Gaussian gathers light across the seam. uSource is the step's
// input; the draw writes into a copy of it (a texture never reads itself).
uniform sampler2D uSource;
in vec2 v_target;
out vec4 f_color;
void main() {
    f_color = texture(uSource, v_target);
}
