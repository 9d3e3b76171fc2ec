// I_1 and I_2 of the chain (tsd/blur.frag) in ONE pass straight from the dilated irradiance, where
// both Gaussians are narrow against a texel (the head at 1024^2: sigma 0.16 and 0.45 texels at the
// median stretch): each is G(v_k) integrated over the texels (d'Eon & Luebke 2007, 14.4.2: the
// profile integrated over the receiving texel's footprint), which there lies within +-1.5 texels,
// so a 3-tap kernel [a, 1 - 2a, a] per axis with the binned Gaussian's variance V = 2a (its tails
// folded onto the side taps) holds it; separable, so one 3x3 neighbourhood serves both (nine
// fetches, two targets) instead of four 1-D passes of tsd/blur.frag.
// V per texel, axis and Gaussian comes from a table (tsd.py, _narrow_weights: from the stretch map,
// once per mesh and profile). Where the stretch is large (V_2 > 2/3 texel^2) the taps move out to
// +-d texels, d the smallest integer with V_2 <= 2/3 d^2, and a = V / (2 d^2): the variance stays
// exact, as tsd/blur.frag spaces its taps. Premultiplied in and out.
// Both textures are bound with a NEAREST, CLAMP_TO_EDGE sampler (tsd.py) and read at texel centres
// (common/texel.glsl): the same texels, bit for bit, cheaper than texelFetch on llvmpipe.
#include "common/texel.glsl"
uniform sampler2D uSource;   // premultiplied rgb, a = coverage (tsd/dilate.frag)
uniform sampler2D uWeights;  // per texel: binned variance (texel^2) of I_1 along u, v; of I_2 along u, v
layout(location = 0) out vec4 f_first;
layout(location = 1) out vec4 f_second;

void main() {
    ivec2 ip = ivec2(gl_FragCoord.xy);
    ivec2 imax = textureSize(uSource, 0) - 1;
    vec4 V = TEXEL(uWeights, ip);
    vec2 d = max(vec2(1.0), ceil(sqrt(1.5 * V.zw) - 1e-4));  // tap spacing (texels) per axis
    vec4 a = 0.5 * V / vec4(d * d, d * d);
    ivec2 id = ivec2(d);
    ivec2 lo = max(ip - id, ivec2(0)), hi = min(ip + id, imax);  // clamped at the border, like blur.frag
    vec4 s00 = TEXEL(uSource, ivec2(lo.x, lo.y)), s10 = TEXEL(uSource, ivec2(ip.x, lo.y)),
         s20 = TEXEL(uSource, ivec2(hi.x, lo.y));
    vec4 s01 = TEXEL(uSource, ivec2(lo.x, ip.y)), s11 = TEXEL(uSource, ip),
         s21 = TEXEL(uSource, ivec2(hi.x, ip.y));
    vec4 s02 = TEXEL(uSource, ivec2(lo.x, hi.y)), s12 = TEXEL(uSource, ivec2(ip.x, hi.y)),
         s22 = TEXEL(uSource, ivec2(hi.x, hi.y));
    // the u sums of each row first, then v
    vec4 e0 = s00 + s20 - 2.0 * s10, e1 = s01 + s21 - 2.0 * s11, e2 = s02 + s22 - 2.0 * s12;
    vec4 r0 = s10 + a.x * e0, r1 = s11 + a.x * e1, r2 = s12 + a.x * e2;
    f_first = r1 + a.y * (r0 + r2 - 2.0 * r1);
    r0 = s10 + a.z * e0; r1 = s11 + a.z * e1; r2 = s12 + a.z * e2;
    f_second = r1 + a.w * (r0 + r2 - 2.0 * r1);
}
