// 2x2 box reduction to the next level (half resolution). Wide Gaussians hold no fine detail, so
// they are blurred at reduced resolution (d'Eon & Luebke 2007, 14.4.3; Jimenez & Gutierrez 2008).
// The data is premultiplied (rgb = colour x coverage, a = coverage; tsd/blur.frag), so the
// coverage-weighted reduction is the plain mean; the box adds (2^level texel)^2 / 4 of variance per
// axis, which tsd.py takes off the step's Gaussian.
// NEAREST_SAMPLER (tsd.py's chain): uSource is bound with a NEAREST, CLAMP_TO_EDGE sampler and read at
// texel centres: the same texels (the border clamped), bit for bit, cheaper than texelFetch on llvmpipe
// (tsd/blur.frag).
uniform sampler2D uSource;
out vec4 f_color;
#ifdef NEAREST_SAMPLER
#define FETCH(q) textureLod(uSource, (vec2(q) + 0.5) * inv_size, 0.0)
#else
#define FETCH(q) texelFetch(uSource, min(q, m), 0)
#endif
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * 2;
    ivec2 m = textureSize(uSource, 0) - 1;
    vec2 inv_size = 1.0 / vec2(m + 1);
    f_color = 0.25 * (FETCH(p) + FETCH(p + ivec2(1, 0)) +
                      FETCH(p + ivec2(0, 1)) + FETCH(p + ivec2(1, 1)));
}
