// Bench floor: the cheapest full-screen pass over a texture (one fetch, one write per texel).
// A blur pass cannot cost less than this at the same size and format.
uniform sampler2D uSource;
out vec4 f_color;
void main() {
    f_color = texelFetch(uSource, ivec2(gl_FragCoord.xy), 0);
}
