// The light through thin parts (tsd/translucency.frag: (T w, coverage) per texel from its own far
// face), blended over the texel and its 8 neighbours with the tent (1 2 1)^2, over the covered ones:
// where the far face jumps between neighbouring texels (the helix: lit for one, shadowed or
// centimetres away for the next) the light through them changes over three texels, not one; a
// uniform region is unchanged. A separate pass so that each far face is evaluated once, not nine
// times (on llvmpipe the nine evaluations in one pass cost 7x the single one: benchmarks/RESULTS.md,
// round 6). Each neighbour's T was measured from its own texel (the surface distance g to its far
// face, tsd/translucency.frag), one texel off this one's: the excess term is smooth in g.
// The tent as four bilinear taps at the texel's corners: each the mean of a 2 x 2 block, together
// (1 2 1)^2 / 4 over the 3 x 3 texels; the edge clamp (CLAMP_TO_EDGE) repeats the border texels as
// the clamped texelFetch did. A corner lies on texel boundaries, where the bilinear weights are 1/2
// exactly (also at a GPU's 8-bit subtexel precision). uSource is filtered linearly (tsd.py _texture).
uniform sampler2D uSource;
out vec4 f_translucency;

void main() {
    ivec2 c = ivec2(gl_FragCoord.xy);
    vec2 size = vec2(textureSize(uSource, 0));
    vec4 corners = textureLod(uSource, vec2(c) / size, 0.0) + textureLod(uSource, (vec2(c) + vec2(1.0, 0.0)) / size, 0.0) +
                   textureLod(uSource, (vec2(c) + vec2(0.0, 1.0)) / size, 0.0) + textureLod(uSource, (vec2(c) + vec2(1.0)) / size, 0.0);
    vec3 sum = 4.0 * corners.rgb;
    float covered = 4.0 * corners.a;
    // an uncovered texel (no triangle: nothing reads it but the bilinear footprint of an island's
    // edge) keeps 0, as the single-pass version wrote
    bool own = texelFetch(uSource, c, 0).a > 0.0;
    f_translucency = vec4(own ? sum / max(covered, 1.0) : vec3(0.0), 1.0);
}
