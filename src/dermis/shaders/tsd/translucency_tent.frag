// The light through thin parts (tsd/translucency.frag: (T w, coverage) per texel from its own far
// face), blended over the texel and its 8 neighbours with the tent (1 2 1)^2, over the covered ones:
// where the far face jumps between neighbouring texels (the helix: lit for one, shadowed or
// centimetres away for the next) the light through them changes over three texels, not one; a
// uniform region is unchanged. A separate pass so that each far face is evaluated once, not nine
// times (on llvmpipe the nine evaluations in one pass cost 7x the single one: benchmarks/RESULTS.md,
// round 6). Each neighbour's T was measured from its own texel (the surface distance g to its far
// face, tsd/translucency.frag), one texel off this one's: the excess term is smooth in g.
uniform sampler2D uSource;
out vec4 f_translucency;

void main() {
    ivec2 c = ivec2(gl_FragCoord.xy);
    ivec2 last = textureSize(uSource, 0) - 1;
    vec3 sum = vec3(0.0);
    float covered = 0.0;
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            vec4 t = texelFetch(uSource, clamp(c + ivec2(dx, dy), ivec2(0), last), 0);
            float tent = float((2 - abs(dx)) * (2 - abs(dy)));
            sum += tent * t.rgb;
            covered += tent * t.a;
        }
    }
    // an uncovered texel (no triangle: nothing reads it but the bilinear footprint of an island's
    // edge) keeps 0, as the single-pass version wrote
    bool own = texelFetch(uSource, c, 0).a > 0.0;
    f_translucency = vec4(own ? sum / max(covered, 1.0) : vec3(0.0), 1.0);
}
