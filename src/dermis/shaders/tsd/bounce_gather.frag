// Interreflection, step 2 (dermis/geometry/interreflection.py): one fragment per mesh vertex (vertex
// v at (v mod P, v div P)) gathers the one-bounce irradiance of its K cosine-weighted rays,
//   E_b = (pi / K) sum_k L_o(y_k) = (1 / K) sum_k rho E(y_k),
// reading rho E (tsd/bounce_exitant.frag, premultiplied by coverage, reduced to ~2 mm texels) at
// each hit's texture-space (u, v). Rays that escape or hit a face turned away hold (-1, -1): they
// add nothing (the environment's share is the ambient occlusion's).
// With BOUNCE_BASE it is one step of the higher bounces (dermis.gl.interreflection.BounceSeries):
// uExitant holds rho T_(n-1) (tsd/bounce_splat.frag with BOUNCE_EXITANT) and the pass writes
//   T_n = E_b + (1 / K) sum_k rho T_(n-1)(y_k) = E_b + G T_(n-1),
// E_b the one bounce (uBase, this layout): after n - 1 steps, E_b + G E_b + ... + G^(n-1) E_b.
uniform sampler2D uHits;     // rg32f, K texels per vertex: the hits' texture-space (u, v)
uniform sampler2D uExitant;  // rho E, premultiplied (rgb x coverage, coverage)
uniform int uRays;
uniform int uVerticesPerRow;
uniform int uVertexCount;
#ifdef BOUNCE_BASE
uniform sampler2D uBase;  // E_b per vertex, the one bounce (this pass's layout)
#endif
#ifdef BOUNCE_MERGED
// the one bounce over all the bake's rays, merged per bilinear cell of uExitant
// (dermis.geometry.interreflection.merge_hits): entries (u, v, share), share = rays merged / K
uniform isampler2D uHeader;  // (offset, count) of this vertex's entries (this pass's layout)
uniform sampler2D uEntries;  // rgb32f, entry e at (e mod 4096, e div 4096) (InterreflectionHits.ENTRY_ROW)
#endif
out vec4 f_bounce;

// a hit in a texel the layout barely covers at this level: its colour is the coverage's ratio of
// two small numbers (half floats); below this it is left out (a slight loss, no speck)
const float MIN_COVERAGE = 1.0 / 64.0;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 sum = vec3(0.0);
#ifdef BOUNCE_MERGED
    if (p.y * uVerticesPerRow + p.x < uVertexCount) {
        ivec2 oc = texelFetch(uHeader, p, 0).xy;
        for (int e = oc.x; e < oc.x + oc.y; ++e) {
            vec3 h = texelFetch(uEntries, ivec2(e & 4095, e >> 12), 0).xyz;
            vec4 c = textureLod(uExitant, h.xy, 0.0);
            if (c.a >= MIN_COVERAGE) sum += h.z * (c.rgb / c.a);
        }
    }
    vec3 e = sum;
#else
    if (p.y * uVerticesPerRow + p.x < uVertexCount) {
        for (int k = 0; k < uRays; ++k) {
            vec2 uv = texelFetch(uHits, ivec2(p.x * uRays + k, p.y), 0).xy;
            if (uv.x < 0.0) continue;
            vec4 c = textureLod(uExitant, uv, 0.0);
            if (c.a >= MIN_COVERAGE) sum += c.rgb / c.a;
        }
    }
    vec3 e = sum / float(max(uRays, 1));
#endif
#ifdef BOUNCE_BASE
    e += texelFetch(uBase, p, 0).rgb;
#endif
    f_bounce = vec4(e, 1.0);
}
