// The horizontal pass's result, packed for the vertical pass: per pixel its view depth (float32
// bits), its view-space normal and each Gaussian's light as halves (packHalf2x16), in
// SSSS_PACKED RGBA32UI texels, so that each vertical tap reads SSSS_PACKED texels (3 for K = 6)
// instead of K images + the irradiance (depth) + the normal. Halves are what the separate
// RGBA16F images and the RGBA16F normal held: the same values.
// uint 0: depth; uints 1..: halves h[0..2] = normal, h[3] = the rejected share,
// h[4 + 3 (K - 1 - k) + c] = Gaussian k's channel c: the widest first, so that the vertical pass's
// outer taps, which read only the wide Gaussians (ssss/kernel.glsl ssss_blur's tiers), fetch only
// the first ssss_packed_texels(first_k) texels.

// A half's bits -> float, exactly for every finite half: the half's exponent and mantissa shifted
// into a float's and its exponent rebased (+ 127 - 15); a zero or subnormal half (exponent 0) as
// the normal float 2^-14 (1 + m / 1024) less 2^-14, so that no float subnormal is formed (llvmpipe
// flushes those to zero); then the sign (F. Giesen, "half_to_float_fast3", 2012). None of the halves
// stored is infinite or NaN (the frame's check rejects such light) and those are not handled. On
// llvmpipe (Mesa 22.3) unpackHalf2x16 costs several times this: the vertical pass 146 -> 115 CPU ms
// at 768 px (round 24, ssss24). tests/test_ssss_kernel.py checks every finite half against numpy.
vec2 ssss_unpack_half2(uint u) {
    uvec2 h = uvec2(u & 0xffffu, u >> 16);
    uvec2 m = (h & 0x7fffu) << 13;
    uvec2 o = m + ((127u - 15u) << 23);
    vec2 small = uintBitsToFloat(o + (1u << 23)) - uintBitsToFloat(113u << 23);  // 2^-14 (m / 1024)
    vec2 f = mix(uintBitsToFloat(o), small, equal(m & (0x1fu << 23), uvec2(0u)));
    return uintBitsToFloat(floatBitsToUint(f) | ((h & 0x8000u) << 16));
}

const int SSSS_HALVES = 3 * MAX_GAUSSIANS + 4;
const int SSSS_UINTS = 1 + (SSSS_HALVES + 1) / 2;
#define SSSS_PACKED ((1 + (3 * MAX_GAUSSIANS + 5) / 2 + 3) / 4)

// The texels holding the depth, normal, rejected share and Gaussians first_k..K-1: Gaussian
// first_k's last half is h[3K + 3 - 3 first_k], in uint 1 + that / 2.
int ssss_packed_texels(int first_k) {
    return (1 + (3 * MAX_GAUSSIANS + 3 - 3 * first_k) / 2) / 4 + 1;
}

int ssss_light_half(int k, int c) {
    return 4 + 3 * (MAX_GAUSSIANS - 1 - k) + c;
}

void ssss_pack(float depth_mm, vec3 normal, vec3 light[MAX_GAUSSIANS], float rejected, out uvec4 texels[SSSS_PACKED]) {
    float h[2 * SSSS_UINTS];
    h[0] = normal.x; h[1] = normal.y; h[2] = normal.z;
    h[3] = rejected;
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        h[ssss_light_half(k, 0)] = light[k].r; h[ssss_light_half(k, 1)] = light[k].g; h[ssss_light_half(k, 2)] = light[k].b;
    }
    for (int i = SSSS_HALVES; i < 2 * SSSS_UINTS; ++i) h[i] = 0.0;
    uint u[4 * SSSS_PACKED];
    u[0] = floatBitsToUint(depth_mm);
    for (int i = 1; i < SSSS_UINTS; ++i) u[i] = packHalf2x16(vec2(h[2 * i - 2], h[2 * i - 1]));
    for (int i = SSSS_UINTS; i < 4 * SSSS_PACKED; ++i) u[i] = 0u;
    for (int t = 0; t < SSSS_PACKED; ++t) texels[t] = uvec4(u[4 * t], u[4 * t + 1], u[4 * t + 2], u[4 * t + 3]);
}

void ssss_unpack(uvec4 texels[SSSS_PACKED], out float depth_mm, out vec3 normal, out vec3 light[MAX_GAUSSIANS],
                 out float rejected) {
    uint u[4 * SSSS_PACKED];
    for (int t = 0; t < SSSS_PACKED; ++t) {
        u[4 * t] = texels[t].x; u[4 * t + 1] = texels[t].y; u[4 * t + 2] = texels[t].z; u[4 * t + 3] = texels[t].w;
    }
    float h[2 * SSSS_UINTS];
    for (int i = 1; i < SSSS_UINTS; ++i) {
        vec2 v = ssss_unpack_half2(u[i]);
        h[2 * i - 2] = v.x; h[2 * i - 1] = v.y;
    }
    depth_mm = uintBitsToFloat(u[0]);
    normal = vec3(h[0], h[1], h[2]);
    for (int k = 0; k < MAX_GAUSSIANS; ++k)
        light[k] = vec3(h[ssss_light_half(k, 0)], h[ssss_light_half(k, 1)], h[ssss_light_half(k, 2)]);
    rejected = h[3];
}
