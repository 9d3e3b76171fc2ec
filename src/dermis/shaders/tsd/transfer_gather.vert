// Subsurface transfer, step 1 (dermis/subsurface_transfer: the bake; dermis/gl/subsurface_transfer.py):
// one point per bake point p, drawn at its texel of the bake's grid (its texture-space uv), carrying
//   T_geo(p) = sum_k w_k I(uv_k),
// the same-side transport that a thin, curled geometry adds to the flat profile of tsd's blurs:
// w_k the bake's RGB tap weights (the skin walk's transfer less the flat medium's at the same
// distance along the surface, in the irradiance map's units; tap 0 is the point itself, negative
// where a thin sheet loses light to its far face), I a blurred irradiance I_k (premultiplied by
// coverage) at the taps' uv. Tap k of point p
// is the texel (x * K + k, y) with (x, y) = (p mod P, p div P), P = points per row.
layout(location = 0) in vec2 in_uv;
uniform sampler2D uTapUv;      // rg32f: the taps' texture-space uv
uniform sampler2D uTapWeight;  // rgba32f: the taps' RGB weights (0: unused)
uniform sampler2D uIrradiance; // rgb x coverage, coverage
uniform int uTaps;
uniform int uPointsPerRow;
flat out vec3 v_transfer;

// a tap in a texel the layout barely covers at this level: the colour is a ratio of two small
// numbers (half floats); below this it is left out, as tsd/bounce_gather.frag does
const float MIN_COVERAGE = 1.0 / 64.0;

void main() {
    ivec2 base = ivec2((gl_VertexID % uPointsPerRow) * uTaps, gl_VertexID / uPointsPerRow);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < uTaps; ++k) {
        vec3 w = texelFetch(uTapWeight, base + ivec2(k, 0), 0).rgb;
        if (w == vec3(0.0)) continue;
        vec4 c = textureLod(uIrradiance, texelFetch(uTapUv, base + ivec2(k, 0), 0).xy, 0.0);
        if (c.a >= MIN_COVERAGE) sum += w * (c.rgb / c.a);
    }
    v_transfer = sum;
    gl_Position = vec4(in_uv * 2.0 - 1.0, 0.0, 1.0);
}
