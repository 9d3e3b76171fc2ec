// Gutter dilation: texels outside every UV island (coverage 0) take the coverage-weighted mean
// colour of their 3x3 neighbours, so bilinear lookups at island borders (and MSAA samples that
// fall just outside a triangle's UVs) never read black. The output is premultiplied for the blur
// chain (tsd/blur.frag): a gutter texel gets the coverage GUTTER_COVERAGE, enough to carry its
// colour where no island's light reaches, too little to shift an island's edge (at most
// GUTTER_COVERAGE of the gutter's weight, and the gutter holds the edge's own colour).
// uSource is bound with the NEAREST, CLAMP_TO_EDGE sampler (tsd.py, _pass(nearest=True)): TEXEL reads
// the texel, a neighbour past the border the edge texel, as texelFetch of the clamped texel did
#include "common/texel.glsl"
uniform sampler2D uSource;
const float GUTTER_COVERAGE = 1.0 / 256.0;
in vec2 v_uv;
out vec4 f_color;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = TEXEL(uSource, p);
    if (c.a >= 0.999) { f_color = c; return; }
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x) {
            vec4 n = TEXEL(uSource, p + ivec2(x, y));
            float w = n.a > 0.0 ? n.a : (dot(n.rgb, n.rgb) > 0.0 ? 0.05 : 0.0);  // earlier dilation counts a little
            sum += n.rgb * w;
            wsum += w;
        }
    vec3 rgb = wsum > 0.0 ? sum / wsum : c.rgb;
    float a = max(c.a, dot(rgb, rgb) > 0.0 ? GUTTER_COVERAGE : 0.0);
    f_color = vec4(rgb * a, a);
}
