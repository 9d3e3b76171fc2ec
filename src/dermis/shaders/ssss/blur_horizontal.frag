// Separable SSS, pass 2: the horizontal 1-D blur, one result per Gaussian of the profile
// (ssss/kernel.glsl): rgb_k = sum_taps g_k E / sum_taps g_k, packed with the pixel's depth and
// normal for the vertical pass (ssss/packing.glsl).
// Written TRANSPOSED: the fragment at (i, j) of the (H, W) packed target computes and stores
// pixel (j, i) of the frame, so that the vertical pass's taps, which step along a column of
// the frame, read along a ROW of the packed images (llvmpipe stores textures row by row: a
// column's taps are a row's size apart, one cache line and often one page each; read along
// rows, neighbouring taps share lines. Round 22: the vertical pass's fetches were half its
// time, the horizontal pass's a tenth: RESULTS "Round 22, branch sssperf22").
#include "ssss/kernel.glsl"
#include "ssss/packing.glsl"

layout(location = 0) out uvec4 f_packed[SSSS_PACKED];

void ssss_fetch(ivec2 q, bool centre, const int first_k, out float depth_mm, out vec3 normal,
                out vec3 light[MAX_GAUSSIANS], out float rejected) {
    rejected = 0.0;
    vec4 t = TEXEL(uIrradiance, q);
    depth_mm = t.a;
    normal = centre ? TEXEL(uViewNormal, q).xyz : ssss_tap_normal(q);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) light[k] = t.rgb;  // the pre-scatter light, the same for every Gaussian
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.yx);  // the frame's pixel (the target is transposed, above)
    vec4 c = TEXEL(uIrradiance, p);
    vec3 blurred[MAX_GAUSSIANS];
    bool wide[MAX_GAUSSIANS];
    float rejected = 0.0;
    if (c.a > 0.0) {
        ssss_blur(p, 0, blurred, wide, rejected);
    } else {
        for (int k = 0; k < MAX_GAUSSIANS; ++k) blurred[k] = c.rgb;
    }
    ssss_pack(c.a, TEXEL(uViewNormal, p).xyz, blurred, rejected, f_packed);
}
