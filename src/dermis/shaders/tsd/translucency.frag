// Translucency through thin parts (d'Eon & Luebke 2007, 14.5.3) with a baked thickness: for the
// texel B, uThickness (dermis/geometry/thickness.py) holds the point A where tissue ends behind B
// along -N (as its texture-space (u, v)) and the thickness d (mm) between them. The light that
// comes THROUGH the tissue from the far face is the far face's irradiance, spread laterally by the
// wide Gaussians' blurred irradiances I_k(A) (their weights' share W_k = w_k / sum_wide w), times
// the slab law T(d) / A of common/thin_slab.glsl (diffusion theory of a slab of the medium the
// profile describes; d'Eon's exp(-d^2 / 2 v_k), the semi-infinite profile's tail, is 1.7-2.8x under
// the slab's Monte Carlo): exact for a uniformly lit slab whatever the light's direction, and
// shadowed as the far face is.
//
// Where -N finds no far face (concha, antihelix edge-on) the bake takes the far face along the key
// light (the TSM's distance, by ray casting) where the two faces form a slab, with a weight; the
// bake is smoothed within UV islands (geometry/thickness.py: translucency_thickness).
// Why not the TSM's distance along the light everywhere: an ear nearly edge-on to the light has a path along
// the light many times its thickness, so exp(-t^2 / 2v) left only a faint rim (back-ears); the
// light spreads through the ear's thickness, not along the light. And a texel just past the
// terminator of a thick part (nose, jaw) has its own neighbour as the TSM's entry point (t -> 0),
// while behind it along -N there are centimetres of tissue: no terminator lines.
//
// The blur chain has already carried the light of A to B ALONG the surface, with Gaussian k's
// kernel exp(-g^2 / 2 v_k) G(v_k, r) for a surface distance g; light reaches B by the shorter
// path, so only the excess of the path through the tissue is added:
//   T_k = w_k I_k(A) max(0, T(d) / (A sum_wide w) - exp(-g^2 / 2 v_k)),
// g measured in the texture (|uv_A - uv_B| in texels over the stretch, texels per mm): exact for a
// flat layout, longer across a UV seam (A and B in different islands: the whole T_k remains).
// Only the wide Gaussians (variance >= uTranslucencyMinVariance) are used, the narrow ones carry
// nothing through millimetres of tissue. Computed in texture space: view-independent, cached.
#include "tsd/gaussians.glsl"
#include "common/thin_slab.glsl"

uniform float uTranslucencyMinVariance;
uniform float uTranslucencyStrength;
uniform sampler2D uStretch;    // texels per mm along u, v (tsd/stretch.frag)
uniform sampler2D uThickness;  // (u, v) of the far face, thickness in mm, weight (geometry/thickness.py)
// 1: only the texels with a far face (weight w > 0) are written; the others keep (0, coverage), which
// depends on the bake alone and was written by an earlier pass with 0 from the same bake into the
// same target (tsd.py redraws it whole when either changes). On the head at 512^2 13% of the texels
// (15% of the 4 x 4 blocks) have a far face: on a GPU the other warps end here. On llvmpipe the pass
// costs half of what it cost without this line whether or not the discard fires (measured, the
// mechanism not found: benchmarks/RESULTS.md, round 10, perf10).
uniform int uFarFaceOnly;
// TRANSLUCENCY_STATIC's output for this bake, stretch and profile (tsd.py keeps it until one changes)
uniform sampler2D uStatic;

// What of the light through the tissue does not depend on the lighting, for the texel at uv whose
// far face the bake holds in th (its (u, v), thickness, weight): the slab law over the wide weights'
// sum, T(d) / (A sum_wide w) per channel, and g, the surface distance from A to B (mm)
vec4 far_face_static(vec4 th, vec2 uv) {
    vec3 wide = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        if (uVariances[k] >= uTranslucencyMinVariance) wide += uWeights[k];
    }
    vec2 stretch = max(texture(uStretch, uv).xy, vec2(1e-6));
    vec2 texels = (th.xy - uv) * vec2(textureSize(uStretch, 0));
    float g = length(texels / stretch);  // mm along the surface from A to B
    return vec4(slab_transmittance(th.z) / max(wide, vec3(1e-6)), g);  // through: per unit of the wide weights
}

#ifdef TRANSLUCENCY_STATIC
// once per bake, stretch and profile: far_face_static per texel (rgba32f: the same floats as if the
// light's pass computed them itself)
out vec4 f_static;
void main() {
    vec2 uv = gl_FragCoord.xy / vec2(textureSize(uThickness, 0));  // this texel's texture-space uv
    vec4 th = texelFetch(uThickness, ivec2(gl_FragCoord.xy), 0);
    f_static = th.w > 0.0 ? far_face_static(th, uv) : vec4(0.0);
}
#else
out vec4 f_translucency;

// The light through the tissue to this texel from the far face that the bake holds in th (its (u, v),
// thickness, weight), over the bake's weight; st: far_face_static at this texel.
vec3 through_far_face(vec4 th, vec4 st) {
    vec3 through = st.rgb;
    float g = st.a;
    vec3 T = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        if (uVariances[k] < uTranslucencyMinVariance) continue;
        vec3 excess = max(through - exp(-g * g / (2.0 * uVariances[k])), vec3(0.0));
        T += excess * uWeights[k] * blurred_irradiance(k, th.xy);
    }
    return T;
}

// This texel's own far face: (T w, coverage), the light through the tissue times the bake's weight
// (smoothed validity; the light path's slab test), and 1 where a triangle covers the texel (the bake
// marks uncovered texels w = -1). tsd/translucency_tent.frag blends the 3 x 3 neighbourhood.
void main() {
    ivec2 c = ivec2(gl_FragCoord.xy);
    vec4 th = texelFetch(uThickness, c, 0);
    if (uFarFaceOnly != 0 && th.w <= 0.0) discard;
    vec3 T = vec3(0.0);
    if (th.w > 0.0) T = th.w * through_far_face(th, texelFetch(uStatic, c, 0));
    f_translucency = vec4(T * uTranslucencyStrength, th.w >= 0.0 ? 1.0 : 0.0);
}
#endif
