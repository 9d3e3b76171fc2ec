// Subsurface transfer, step 1b: the view grids' 2x2 box sums at the level the readers read
// (common/subsurface_transfer.glsl: subsurface_transfer_view), so that a reader's tent over 3x3 texels is
// a bilinear blend of 2x2 of these: per axis the tent's weights (1 - f) / 2, 1 / 2, f / 2 on texels
// i0, i0 + 1, i0 + 2 are (1 - f) / 2 (g_i0 + g_i0+1) + f / 2 (g_i0+1 + g_i0+2), the same sum with 4 image
// loads per grid instead of 9 (on llvmpipe the loads were ~80 % of the view term's cost, round 23).
// Texel k of the target (size + 1 per axis) holds the grid's texels k - 1 and k per axis, clamped to the
// grid as the reader clamped them, so a reader at any uv reads it clamped to [0, size] and sums what it
// summed before. Runs after every gather (dermis.gl.subsurface_transfer.SubsurfaceTransfer.view_box).
uniform sampler2D uViewR;  // the view grids (red, green, blue: tsd/transfer_gather.frag's attachments 1-3)
uniform sampler2D uViewG;
uniform sampler2D uViewB;
uniform int uLevel;  // the grids' level the readers read (uTransferLevel)
layout(location = 0) out vec4 f_box_r;
layout(location = 1) out vec4 f_box_g;
layout(location = 2) out vec4 f_box_b;

// grid g's texels a, (b.x, a.y), (a.x, b.y), b at uLevel, summed
vec4 box_sum(sampler2D g, ivec2 a, ivec2 b) {
    return texelFetch(g, a, uLevel) + texelFetch(g, ivec2(b.x, a.y), uLevel)
         + texelFetch(g, ivec2(a.x, b.y), uLevel) + texelFetch(g, b, uLevel);
}

void main() {
    ivec2 size = textureSize(uViewR, uLevel);
    ivec2 k = ivec2(gl_FragCoord.xy);
    ivec2 a = clamp(k - 1, ivec2(0), size - 1), b = clamp(k, ivec2(0), size - 1);
    f_box_r = box_sum(uViewR, a, b);
    f_box_g = box_sum(uViewG, a, b);
    f_box_b = box_sum(uViewB, a, b);
}
