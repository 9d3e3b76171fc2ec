// Procedural pore-scale detail: 3-D gradient noise (Perlin 2002, "Improving Noise", with a hash in
// place of the permutation table) and its analytic gradient, evaluated on world positions in mm so
// the detail has a physical scale. Used to perturb the specular normal (d'Eon & Luebke 2007, 14.5:
// "pore-level detail ... in the specular").
#include "common/constants.glsl"
vec3 noise_hash3(vec3 p) {
    p = vec3(dot(p, vec3(127.1, 311.7, 74.7)), dot(p, vec3(269.5, 183.3, 246.1)), dot(p, vec3(113.5, 271.9, 124.6)));
    return -1.0 + 2.0 * fract(sin(p) * 43758.5453123);
}

// Returns (value, gradient) of gradient noise with quintic fade; value in about [-1, 1].
vec4 gradient_noise_d(vec3 x) {
    vec3 i = floor(x);
    vec3 f = x - i;
    vec3 u = f * f * f * (f * (f * 6.0 - 15.0) + 10.0);
    vec3 du = 30.0 * f * f * (f * (f - 2.0) + 1.0);
    vec3 ga = noise_hash3(i + vec3(0, 0, 0)), gb = noise_hash3(i + vec3(1, 0, 0));
    vec3 gc = noise_hash3(i + vec3(0, 1, 0)), gd = noise_hash3(i + vec3(1, 1, 0));
    vec3 ge = noise_hash3(i + vec3(0, 0, 1)), gf = noise_hash3(i + vec3(1, 0, 1));
    vec3 gg = noise_hash3(i + vec3(0, 1, 1)), gh = noise_hash3(i + vec3(1, 1, 1));
    float va = dot(ga, f - vec3(0, 0, 0)), vb = dot(gb, f - vec3(1, 0, 0));
    float vc = dot(gc, f - vec3(0, 1, 0)), vd = dot(gd, f - vec3(1, 1, 0));
    float ve = dot(ge, f - vec3(0, 0, 1)), vf = dot(gf, f - vec3(1, 0, 1));
    float vg = dot(gg, f - vec3(0, 1, 1)), vh = dot(gh, f - vec3(1, 1, 1));
    float v = va + u.x * (vb - va) + u.y * (vc - va) + u.z * (ve - va) + u.x * u.y * (va - vb - vc + vd)
            + u.y * u.z * (va - vc - ve + vg) + u.z * u.x * (va - vb - ve + vf)
            + u.x * u.y * u.z * (-va + vb + vc - vd + ve - vf - vg + vh);
    vec3 g = ga + u.x * (gb - ga) + u.y * (gc - ga) + u.z * (ge - ga) + u.x * u.y * (ga - gb - gc + gd)
           + u.y * u.z * (ga - gc - ge + gg) + u.z * u.x * (ga - gb - ge + gf)
           + u.x * u.y * u.z * (-ga + gb + gc - gd + ge - gf - gg + gh)
           + du * (vec3(vb - va, vc - va, ve - va) + u.yzx * vec3(va - vb - vc + vd, va - vc - ve + vg, va - vb - ve + vf)
                   + u.zxy * vec3(va - vb - ve + vf, va - vb - vc + vd, va - vc - ve + vg)
                   + u.yzx * u.zxy * (-va + vb + vc - vd + ve - vf - vg + vh));
    return vec4(v, g);
}

// Perturb N by the surface gradient of two octaves of noise at pore scale (bump mapping,
// Blinn 1978): N' = normalize(N - strength * (grad - N (N.grad))). P_mm in millimetres.
// Each octave fades out as its wavelength approaches the pixel's footprint on the surface (the
// noise would alias into sparkle): a frequency clamp (Perlin 1985; Lagae et al. 2010, sec. 3).
// Fragment shaders only (uses derivatives).
// DERMIS_PORES_INVISIBLE: the program variant drawn where no pixel's footprint is below half the
// pore scale (f1 = 0 at every fragment, so N comes back unchanged; dermis.techniques.shared.
// pores_invisible): the same image without the noise, which a CPU rasteriser (llvmpipe) evaluates
// under the false branch anyway (it runs both sides of a branch under a mask).
vec3 pore_normal(vec3 N, vec3 P_mm, float pore_scale_mm, float strength) {
#ifdef DERMIS_PORES_INVISIBLE
    return N;
#else
    if (strength <= 0.0 || pore_scale_mm <= 0.0) return N;
    float footprint_mm = max(length(dFdx(P_mm)), length(dFdy(P_mm)));
    float f1 = 1.0 - smoothstep(DERMIS_PORE_FADE.x, DERMIS_PORE_FADE.y, footprint_mm / pore_scale_mm);
    float f2 = 1.0 - smoothstep(DERMIS_PORE_FADE.x, DERMIS_PORE_FADE.y, footprint_mm / (0.5 * pore_scale_mm));
    if (f1 <= 0.0) return N;
    vec4 n1 = gradient_noise_d(P_mm / pore_scale_mm);
    vec4 n2 = gradient_noise_d(P_mm / (0.5 * pore_scale_mm) + 17.0);
    vec3 g = f1 * n1.yzw + 0.5 * f2 * n2.yzw;
    vec3 gt = g - N * dot(N, g);
    return normalize(N - strength * gt);
#endif
}
