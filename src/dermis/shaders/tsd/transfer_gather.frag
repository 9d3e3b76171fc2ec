// Subsurface transfer, step 1 (dermis/subsurface_transfer: the bake; dermis/gl/subsurface_transfer.py):
// at each texel of the bake's grid that holds a bake point p (uPoint: tsd/transfer_index.vert's map;
// drawn over the tiles holding one, tsd/transfer_tiles.vert),
//   T_geo(p) = sum_k w_k I(uv_k),
// the same-side transport that a thin, curled geometry adds to the flat profile of tsd's blurs:
// w_k the bake's RGB tap weights (the skin walk's transfer less the flat medium's at the same
// distance along the surface, in the irradiance map's units; tap 0 is the point itself, negative
// where a thin sheet loses light to its far face), I a blurred irradiance I_k (premultiplied by
// coverage) at the taps' uv. Tap k of point p
// is the texel (x * K + k, y) with (x, y) = (p mod P, p div P), P = points per row.
// The view term (round 22, dermis.subsurface_transfer.bake.view_basis): per channel c the sums
// sum_k (G_x, G_y, G_z, c)_k,c I_c(uv_k) of the taps' view coefficients (uTapView0-2: red, green, blue),
// which common/subsurface_transfer.glsl turns into the transfer seen along the fragment's view.
// Attachment 0 the cosine views' T_geo (alpha 1 at a point), 1-3 the view term's of red, green, blue;
// 0 at a texel without a point. Until round 23 the vertex stage of one GL point per bake point
// computed these (the same sums, bit for bit): ~8 of the pass's ~18 CPU ms on llvmpipe, ~5.5 as
// fragments (round 24, xfer24). Its reads are texel reads at texel centres (common/texel.glsl TEXEL,
// the tables' and the point map's own NEAREST filter): bit-identical to texelFetch, ~0.9 CPU ms less on
// the head (round 24).
#include "common/texel.glsl"
uniform isampler2D uPoint;     // r32i: the bake point at each grid texel, -1: none (NEAREST)
uniform sampler2D uTapUv;      // rg32f: the taps' texture-space uv (this and the four tap tables below: NEAREST)
uniform sampler2D uTapWeight;  // rgba32f: the taps' RGB weights (0: unused)
uniform sampler2D uTapView0;   // rgba32f: the taps' view coefficients (G_x, G_y, G_z, c) of red
uniform sampler2D uTapView1;   // ... of green
uniform sampler2D uTapView2;   // ... of blue
uniform sampler2D uIrradiance; // rgb x coverage, coverage
uniform int uTaps;
uniform int uPointsPerRow;
layout(location = 0) out vec4 f_transfer;
layout(location = 1) out vec4 f_view_r;
layout(location = 2) out vec4 f_view_g;
layout(location = 3) out vec4 f_view_b;

// a tap in a texel the layout barely covers at this level: the colour is a ratio of two small
// numbers (half floats); below this it is left out, as tsd/bounce_gather.frag does
const float MIN_COVERAGE = 1.0 / 64.0;

void main() {
    int p = TEXEL(uPoint, ivec2(gl_FragCoord.xy)).r;
    if (p < 0) {  // a tile's texel without a point: the 0 it was cleared to
        f_transfer = f_view_r = f_view_g = f_view_b = vec4(0.0);
        return;
    }
    ivec2 base = ivec2((p % uPointsPerRow) * uTaps, p / uPointsPerRow);
    vec3 sum = vec3(0.0);
    vec4 vr = vec4(0.0), vg = vec4(0.0), vb = vec4(0.0);
    for (int k = 0; k < uTaps; ++k) {
        ivec2 t = base + ivec2(k, 0);
        vec3 w = TEXEL(uTapWeight, t).rgb;
        if (w == vec3(0.0)) continue;
        vec4 c = textureLod(uIrradiance, TEXEL(uTapUv, t).xy, 0.0);
        if (c.a >= MIN_COVERAGE) {
            vec3 I = c.rgb / c.a;
            sum += w * I;
            vr += TEXEL(uTapView0, t) * I.r;
            vg += TEXEL(uTapView1, t) * I.g;
            vb += TEXEL(uTapView2, t) * I.b;
        }
    }
    f_transfer = vec4(sum, 1.0);
    f_view_r = vr;
    f_view_g = vg;
    f_view_b = vb;
}
