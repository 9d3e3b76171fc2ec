// Seam fill: a gutter texel beside a UV seam takes the blur step's input at the same surface point in
// the neighbouring chart (dermis.geometry.seams: its bilinear taps there), premultiplied as the chain's
// data (tsd/blur.frag), so the next Gaussian gathers light across the seam; a step fills the texels
// within its own reach of the seam (uReach) and leaves every other texel of its rectangles (discard).
// Drawn into the texture it reads: no tap lies on a texel any fill writes (bilinear_taps), which GL 4.5
// defines (9.3.1, disjoint sets of texels).
uniform sampler2D uSource;
uniform sampler2D uFill;     // x = the taps' lower-left texel as y * width + x, y = distance from the seam (mesh units; 1e30: none)
uniform sampler2D uWeights;  // the taps' weights (+0,+0), (+1,+0), (+0,+1), (+1,+1), unorm8
uniform float uReach;        // mesh units
out vec4 f_color;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec2 f = texelFetch(uFill, p, 0).xy;
    if (!(f.y <= uReach)) discard;
    ivec2 size = textureSize(uSource, 0);
    int i = int(f.x + 0.5);
    ivec2 b = ivec2(i % size.x, i / size.x);
    ivec2 m = size - 1;
    vec4 w = texelFetch(uWeights, p, 0);
    w /= max(dot(w, vec4(1.0)), 1e-6);
    f_color = w.x * texelFetch(uSource, min(b, m), 0) + w.y * texelFetch(uSource, min(b + ivec2(1, 0), m), 0)
            + w.z * texelFetch(uSource, min(b + ivec2(0, 1), m), 0) + w.w * texelFetch(uSource, min(b + ivec2(1, 1), m), 0);
}
