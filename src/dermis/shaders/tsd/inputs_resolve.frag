// The prefilter's resolve (dermis.gl.irradiance_inputs): each input target as the weighted mean of
// its subsamples that the mesh covers, sum_k w_k x_k / sum_k w_k over the covered k (the jittered
// rasters added them and their weights by blending), so a texel at a UV island's border averages
// its own island only. A texel whose centre the mesh does not cover is written 0 in every target,
// as the unfiltered raster's clear: the layout's coverage (Ng = 0 off the mesh) stays exactly the
// one raster's, so the dilation and the normalised blurs see the same islands.
// INPUT_COUNT: the input targets (5, or 6 with SKIN_INPUTS_ALBEDO_REST's); uAccum[INPUT_COUNT]: the weights.
uniform sampler2D uAccum[INPUT_COUNT + 1];
layout(location = 0) out vec4 f_0;
layout(location = 1) out vec4 f_1;
layout(location = 2) out vec4 f_2;
layout(location = 3) out vec4 f_3;
layout(location = 4) out vec4 f_4;
#if INPUT_COUNT > 5
layout(location = 5) out vec4 f_5;
#endif
void main() {
    ivec2 t = ivec2(gl_FragCoord.xy);
    vec2 w = texelFetch(uAccum[INPUT_COUNT], t, 0).xy;  // (sum of the covered weights, centre covered)
    float s = (w.y > 0.0 && w.x > 0.0) ? 1.0 / w.x : 0.0;
    f_0 = texelFetch(uAccum[0], t, 0) * s;
    f_1 = texelFetch(uAccum[1], t, 0) * s;
    f_2 = texelFetch(uAccum[2], t, 0) * s;
    f_3 = texelFetch(uAccum[3], t, 0) * s;
    f_4 = texelFetch(uAccum[4], t, 0) * s;
#if INPUT_COUNT > 5
    f_5 = texelFetch(uAccum[5], t, 0) * s;
#endif
}
