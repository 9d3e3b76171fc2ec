// A screen fragment's texture-space UV kept on its own triangle (issue 12, round 12).
// Why: with multisampling a fragment shader runs once per pixel and primitive, and a varying
// without the centroid or sample qualifier is interpolated at the pixel centre even where only an
// edge sample is covered: outside the primitive (GLSL 4.50, 4.5 "Interpolation Qualifiers"). A
// triangle seen edge-on (the nose wing's fold in front-key: |N.V| ~ 0.03, ~0.1 px wide on screen,
// 7 texels^2 in the 1024^2 layout) changes its UV by texels per pixel, so that UV lands 2-5 texels
// off the triangle, on the lit outer wing or nostril rim: the sample reads 2-3.5x (red) and 3-11x
// (green) the irradiance of its own texels, and the pixel, one sample of four, shows a light
// speck (front-key at 768 px, (x, y) = (388, 500), (378, 537), (367, 546), (355, 530): 1.0-1.2
// stops above their 5 x 5 median). The centroid qualifier does not cure it on llvmpipe: the same
// slivers' UVs at their covered samples came out 5-9 texels off (the attribute plane of a
// near-zero-area triangle). So the UV is moved onto the triangle's own UV footprint: the closest
// point of its UV triangle (dermis.gl.resources.GpuScene.triangle_uv_ts, a shader storage buffer
// at TRIANGLE_UV_BINDING: the final pass already uses all 16 guaranteed samplers). Inside the
// triangle, where every sample of an interior pixel is, the UV is returned unchanged.
#ifndef TRIANGLE_UV_BINDING
#define TRIANGLE_UV_BINDING 0
#endif
layout(std430, binding = TRIANGLE_UV_BINDING) readonly buffer TriangleUvTs {
    vec2 triangle_uv_ts[];  // 3 per triangle, in the index buffer's order
};

float cross2(vec2 a, vec2 b) {
    return a.x * b.y - a.y * b.x;
}

// closest point of the segment a-b to p (a point segment when a == b)
vec2 closest_on_segment(vec2 p, vec2 a, vec2 b) {
    vec2 ab = b - a;
    float len2 = dot(ab, ab);
    float t = len2 > 0.0 ? clamp(dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
    return a + t * ab;
}

// closest point of the triangle a b c to p (Ericson 2005, "Real-Time Collision Detection", 5.1.5,
// in 2-D: p itself when inside, else the nearest of the three edges; a triangle of zero area, its
// corners in a line, has only its edges)
// twice the signed areas of (p, b, c), (p, c, a), (p, a, b): the barycentrics of p times twice the
// triangle's signed area cross2(b - a, c - a)
vec3 triangle_weights(vec2 p, vec2 a, vec2 b, vec2 c) {
    return vec3(cross2(b - p, c - p), cross2(c - p, a - p), cross2(a - p, b - p));
}

vec2 closest_on_triangle(vec2 p, vec2 a, vec2 b, vec2 c) {
    float area = cross2(b - a, c - a);
    vec3 w = triangle_weights(p, a, b, c);
    if (area != 0.0 && w.x * area >= 0.0 && w.y * area >= 0.0 && w.z * area >= 0.0) return p;
    vec2 q0 = closest_on_segment(p, a, b), q1 = closest_on_segment(p, b, c), q2 = closest_on_segment(p, c, a);
    vec2 d = vec2(dot(q0 - p, q0 - p), dot(q1 - p, q1 - p));
    vec2 q = d.x <= d.y ? q0 : q1;
    return dot(q2 - p, q2 - p) < min(d.x, d.y) ? q2 : q;
}

// uv moved onto triangle ``primitive``'s UVs (gl_PrimitiveID of a draw of the whole index buffer)
vec2 uv_on_triangle(vec2 uv, int primitive) {
    int i = 3 * primitive;
    return closest_on_triangle(uv, triangle_uv_ts[i], triangle_uv_ts[i + 1], triangle_uv_ts[i + 2]);
}
