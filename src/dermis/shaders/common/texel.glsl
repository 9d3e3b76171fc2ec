// TEXEL(t, q): texel q of t's level 0, read with textureLod at the texel's centre instead of
// texelFetch. On Mesa llvmpipe texelFetch pays bounds checks the sampled path does not: ~0.3-0.4 ms
// less per tap over 1024^2 RGBA16F texels (benchmarks/results/round-23.md, chain23, fetch23).
// t must be read through NEAREST filtering: the texture's own filter (ssss's targets) or the
// NEAREST, CLAMP_TO_EDGE sampler object
// (dermis.gl.resources.nearest_sampler). A centre of any size up to ~16k maps to its texel exactly,
// so the value is the texel's, bit for bit; q outside t reads the edge texel (CLAMP_TO_EDGE), as
// texelFetch of the clamped q did. Not everywhere cheaper: the bounce gather's per-vertex loops
// (rgb32f, rg32i), the seam fill's tables and preintegrated's fold taps measured no gain (fetch23)
// and keep texelFetch.
// A macro, not a function: a helper function changed how the compiler fused the caller's
// arithmetic (1 float16 ulp on 541 texels, chain23).
// Times the reciprocal, not divided by the size: one division per texture, not two per read (the
// compiler computes the identical 1 / size once), the form chain23 measured.
#define TEXEL(t, q) textureLod(t, (vec2(q) + 0.5) * (1.0 / vec2(textureSize(t, 0))), 0.0)
