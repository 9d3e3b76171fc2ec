// 2x2 box reduction to the next level (half resolution). Wide Gaussians hold no fine detail, so
// they are blurred at reduced resolution (d'Eon & Luebke 2007, 14.4.3; Jimenez & Gutierrez 2008).
// The data is premultiplied (rgb = colour x coverage, a = coverage; tsd/blur.frag), so the
// coverage-weighted reduction is the plain mean; the box adds (2^level texel)^2 / 4 of variance per
// axis, which tsd.py takes off the step's Gaussian.
// uSource is bound with the NEAREST, CLAMP_TO_EDGE sampler (tsd.py's chain, LevelChain in
// dermis.gl.interreflection) and read with TEXEL: the same texels (the border clamped), bit for bit,
// cheaper than texelFetch on llvmpipe (common/texel.glsl).
#include "common/texel.glsl"
uniform sampler2D uSource;
out vec4 f_color;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * 2;
    f_color = 0.25 * (TEXEL(uSource, p) + TEXEL(uSource, p + ivec2(1, 0)) +
                      TEXEL(uSource, p + ivec2(0, 1)) + TEXEL(uSource, p + ivec2(1, 1)));
}
