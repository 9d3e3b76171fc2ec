// Bench floor: the cheapest full-screen pass over a texture (one read, one write per texel).
// A blur pass cannot cost less than this at the same size and format. The read goes through the
// texture's NEAREST, CLAMP_TO_EDGE filtering at the texel centre (dermis.bench_floors sets it): on
// llvmpipe ~10 % cheaper than texelFetch, which bounds-checks (benchmarks/results/round-23.md,
// branch chain23), and how tsd's chain reads since round 23, so the floor is the cheaper of the two.
uniform sampler2D uSource;
out vec4 f_color;
void main() {
    f_color = textureLod(uSource, (floor(gl_FragCoord.xy) + 0.5) / vec2(textureSize(uSource, 0)), 0.0);
}
