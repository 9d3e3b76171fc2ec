// Separable SSS, pass 3b (option grain_filter, ssss/kernel.glsl "Grain filter"): the scattered
// light of the wide Gaussians, which the blurs drew with their variance less 1/2 px^2 per axis,
// convolved with the 3 x 3 binomial [1 2 1] x [1 2 1] / 16 (variance 1/2 px^2 per axis: the
// Gaussians' own variance restored) and added to the narrow Gaussians' light:
//   rgb = narrow(p) + sum_n b_n wide(n),  a = view depth in mm (copied)
// The binomial is taken in opposite pairs (left-right, up-down, the two diagonals): a pair whose
// either pixel is on another surface (off the mesh, across a depth jump or air: the blurs' own
// rules, ssss_tap_dz_px and ssss_same_tissue) or whose wide Gaussians are not the pixel's (where a
// Gaussian crosses SSSS_FILTER_SIGMA_PX) gives its weight to the pixel's own wide light. A pair
// is symmetric about the pixel, so a dropped pair shifts nothing (a one-sided neighbour dropped
// would pull the light from the other side across a silhouette's last pixel), and energy is kept.
// Back-off: where the blurs put a share r of the widest Gaussian's weight on another surface
// (beside a crease or a silhouette), that share is the pixel's OWN light, so the wide light jumps
// from pixel to pixel by about r W |E_n - E_p| (W the wide Gaussians' share of the profile, per
// channel): a real edge of the result, not noise (tests/test_ssss.py, the dark margin beside a
// crease, where E steps from 0 to 1 six pixels from the crease). A pair fades to the pixel's own
// light as that jump, with max(r_p, r_n), grows from 0 to SSSS_FILTER_JUMP of the pixel's wide
// light in any channel (smoothstep), so the filter moves such an edge by < 1/4 of that.
#include "ssss/kernel.glsl"

uniform sampler2D uNarrow;  // the vertical pass's rgb (Gaussians not filtered), a = view depth mm
// (uIrradiance, ssss/kernel.glsl: pass 1's pre-scatter light E, a = view depth mm)
uniform sampler2D uWide;    // its wide Gaussians' rgb, a = their bit mask + rejected share / 2
out vec4 f_scattered;

const float SSSS_FILTER_JUMP = 0.15;

// The weight (0..1) with which neighbour q enters the filter of pixel p, 0 on another surface.
// c: the pixel's pre-scatter light E and depth; share: the wide Gaussians' share of the profile
// over the pixel's wide light (per channel).
float ssss_filter_accept(ivec2 q, ivec2 size, vec4 c, vec3 pp, vec3 np, float mask, float r, vec3 share, out vec3 light) {
    light = vec3(0.0);
    if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) return 0.0;
    vec4 t = TEXEL(uIrradiance, q);
    vec4 tw = TEXEL(uWide, q);
    light = tw.rgb;
    float tmask = floor(tw.a);
    if (t.a <= 0.0 || tmask != mask || abs(t.a - c.a) > uDepthCutoffMm
        || !ssss_same_tissue(pp, np, q, TEXEL(uViewNormal, q).xyz, t.a, size)) return 0.0;
    vec3 jump = max(r, 2.0 * (tw.a - tmask)) * abs(t.rgb - c.rgb) * share;
    return 1.0 - smoothstep(0.0, SSSS_FILTER_JUMP, max(jump.r, max(jump.g, jump.b)));
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 size = textureSize(uNarrow, 0);
    vec4 narrow = TEXEL(uNarrow, p);
    if (narrow.a <= 0.0) {
        f_scattered = vec4(0.0);
        return;
    }
    vec4 wide = TEXEL(uWide, p);
    float mask = floor(wide.a);
    float r = 2.0 * (wide.a - mask);
    float cz = narrow.a;
    vec3 np = TEXEL(uViewNormal, p).xyz;
    vec4 c = TEXEL(uIrradiance, p);
    vec3 w_wide = vec3(0.0);  // the wide Gaussians' share of the profile (its weights are normalised per channel)
    for (int k = 0; k < MAX_GAUSSIANS; ++k)
        if (k < uGaussianCount && ((int(mask) >> k) & 1) != 0) w_wide += uWeights[k];
    vec3 share = w_wide / max(wide.rgb, vec3(1e-6));
    vec3 pp = ssss_view_position_mm(p, size, cz);
    vec3 sum = vec3(0.0);
    float own = 0.25;  // the binomial's centre weight, and the weight of the pairs dropped
    const ivec2 pairs[4] = ivec2[4](ivec2(1, 0), ivec2(0, 1), ivec2(1, 1), ivec2(1, -1));
    for (int i = 0; i < 4; ++i) {
        float b = i < 2 ? 0.125 : 0.0625;  // each pixel of the pair: 2/16 (edges), 1/16 (corners)
        vec3 la, lb;
        float s = min(ssss_filter_accept(p + pairs[i], size, c, pp, np, mask, r, share, la),
                      ssss_filter_accept(p - pairs[i], size, c, pp, np, mask, r, share, lb));
        sum += b * s * (la + lb);
        own += 2.0 * b * (1.0 - s);
    }
    f_scattered = vec4(narrow.rgb + sum + own * wide.rgb, cz);
}

// not read here (ssss/kernel.glsl declares it for the blurs)
void ssss_fetch(ivec2 q, bool centre, const int first_k, out float depth_mm, out vec3 normal,
                out vec3 light[MAX_GAUSSIANS], out float rejected) {
    depth_mm = 0.0;
    normal = vec3(0.0, 0.0, 1.0);
    rejected = 0.0;
    for (int k = 0; k < MAX_GAUSSIANS; ++k) light[k] = vec3(0.0);
}
