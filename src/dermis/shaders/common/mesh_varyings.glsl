// The varyings of common/mesh.vert for a screen pass's fragment shader (lambert, preintegrated, ssss's final pass), moved
// onto the fragment's own triangle where the pixel centre's extrapolation runs far off it (issue 12,
// rounds 12-18). Include it FIRST in the fragment shader and call load_mesh_varyings() at the top of
// main(): below the #defines at the end of this file the names v_world, v_normal, ... mean global copies.
// Why: with multisampling a fragment shader runs once per pixel and triangle, and a varying without the
// centroid or sample qualifier is interpolated at the pixel centre even where only an edge sample is
// covered: outside the triangle (GLSL 4.50, 4.5 "Interpolation Qualifiers"). On an ordinary triangle that
// point is at most ~0.7 px off it and shades like its neighbour pixel. A triangle seen edge-on (a crease,
// the nostril, the lip line: |N.V| ~ 0.03, ~0.1 px wide on screen) turns that 0.7 px into many pixel
// footprints along its plane: P, N and the UVs are extrapolated millimetres off it and the sample is lit
// as some other surface, a single light pixel (round 18, review18 item 3: side (280, 536) luminance 0.19
// vs 0.04 supersampled; the example's lip line (391, 550) 0.27 vs 0.07).
// So a fragment with an uncovered sample whose pixel centre's point lies more than MESH_MOVE_FOOTPRINTS
// pixel footprints (at the covered point's distance) from the covered point takes every varying at that
// covered point: the mean of its covered samples' points on the triangle (below). Every other fragment
// keeps the plain pixel-centre interpolants bit for bit: the interior, and every ordinary edge fragment
// (rounds 13-14, speck13 / speck14b, moved them all: 50-80 k pixels of a 768 px frame changed, and
// against a 6 x 6 supersampled frame the mean error over them did not drop; round 15 kept main's).
// How the move is made: every varying A is the same affine function of the barycentrics lambda
// (perspective-correct interpolation IS barycentric), so across the 2 x 2 quad (one triangle's planes)
// the finite differences obey dA = J dlambda, and A at the covered point c is A + dA/dx s.x + dA/dy s.y
// with s = [dlambda/dx dlambda/dy]^-1 (lambda_c - lambda), one screen offset for all varyings; lambda
// from each triangle's barycentric frame (dermis.gl.resources.triangle_frames: two texel loads).
// Explicit derivatives (preintegrated's curvature and mip levels) are taken of mesh_raw_* (the plain
// interpolants, affine per triangle).
#define DERMIS_MESH_VARYINGS

in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec2 v_uv1;
in vec4 v_tangent;
in vec2 v_uv_ts;
in vec4 v_visibility;  // (ambient occlusion, visible fraction RGB): common/environment.glsl
in vec3 v_blocked_sh0;  // the L2 SH of the directions the mesh blocks: the specular occlusion
in vec3 v_blocked_sh1;
in vec3 v_blocked_sh2;
noperspective centroid in vec4 c_world_w;  // common/mesh.vert: (position, 1) / w at a covered sample
#ifdef DERMIS_VERTEX_CURVATURE
in float v_curvature;
#endif
#ifdef DERMIS_INTERREFLECTION
in vec3 v_bounce;
#endif
uniform vec3 uCameraPos;
uniform float uPixelRadians;  // the angle one pixel spans at the image centre (dermis.techniques.base.draw_mesh)

#ifndef MESH_TRIANGLE_IMAGE
#define MESH_TRIANGLE_IMAGE 0
#endif
// each triangle's barycentric frame (dermis.gl.resources.triangle_frames: two texels per triangle,
// MESH_TRIANGLES_PER_ROW a row), in triangle order: gl_PrimitiveID of the one draw of the whole index
// buffer (dermis.techniques.base.draw_mesh)
layout(binding = MESH_TRIANGLE_IMAGE, rgba32f) readonly uniform image2D uTriangleFrames;
const int MESH_TRIANGLES_PER_ROW = 2048;
// The move's threshold, in pixel footprints at the covered point (|P_centre - P_covered| / (distance *
// pixel angle)). An ordinary edge fragment's centre is <= 0.71 px from a covered sample, 0.71 / |cos|
// footprints on a plane at angle theta to the view: 2 leaves every triangle with |N.V| > 0.36 as it is.
const float MESH_MOVE_FOOTPRINTS = 2.0;

vec4 frame_b, frame_c;
// The barycentrics (lambda_b, lambda_c) of p's projection into the fragment's own triangle.
vec2 triangle_barycentrics(vec3 p) {
    return vec2(dot(frame_b, vec4(p, 1.0)), dot(frame_c, vec4(p, 1.0)));
}

// A plain interpolant moved by the screen offset s (pixels): exact for any varying of the triangle.
#define MOVED(a, s) ((a) + dFdxFine(a) * (s).x + dFdyFine(a) * (s).y)

vec3 mesh_world, mesh_normal, mesh_raw_world, mesh_raw_normal;
vec2 mesh_uv, mesh_uv1, mesh_uv_ts, mesh_raw_uv, mesh_raw_uv_ts;
vec4 mesh_tangent, mesh_visibility;
vec3 mesh_blocked_sh0, mesh_blocked_sh1, mesh_blocked_sh2;
#ifdef DERMIS_VERTEX_CURVATURE
float mesh_curvature_v;
#endif
#ifdef DERMIS_INTERREFLECTION
vec3 mesh_bounce;
#endif

void load_mesh_varyings() {
    mesh_raw_world = v_world;
    mesh_raw_normal = v_normal;
    mesh_raw_uv = v_uv;
    mesh_raw_uv_ts = v_uv_ts;
    ivec2 at = ivec2(2 * (gl_PrimitiveID % MESH_TRIANGLES_PER_ROW), gl_PrimitiveID / MESH_TRIANGLES_PER_ROW);
    frame_b = imageLoad(uTriangleFrames, at);
    frame_c = imageLoad(uTriangleFrames, at + ivec2(1, 0));
    vec2 l = triangle_barycentrics(v_world);
    // The covered point. Each sample's point is c_world_w's (p / w) / (1 / w) there, perspective-correct
    // (Heckbert & Moreton 1991: p/w and 1/w are affine in screen space; llvmpipe's perspective-correct
    // centroid of a sliver came out farther off than the pixel centre, round 12, the noperspective one
    // within 0.004 of it, round 13); the point's barycentrics are clamped onto the triangle (keeping any
    // rasteriser's rounding on it).
#ifdef DERMIS_MESH_VARYINGS_CENTROID  // (a control: the centroid, one covered sample)
    vec3 c_world = c_world_w.xyz / c_world_w.w;
#else
    // the mean of the covered samples' points: the resolve weights this fragment's one shade by all of
    // them, and at a rim, where the light changes fast across the pixel, one of them (the centroid) is
    // an extreme (round 14, speck14b; here the back-lit ear lobe's rim, back-ears (288, 577) at 768 px:
    // 0.38 with the centroid, 0.16 supersampled). interpolateAtSample does not make the shader run per
    // sample (gl_SamplePosition would: GLSL 4.50, 8.13.1)
    vec4 c_sum = vec4(0.0);
    for (int i = 0; i < gl_NumSamples; ++i) {
        if ((gl_SampleMaskIn[0] & (1 << i)) != 0) {
            vec4 c = interpolateAtSample(c_world_w, i);
            c_sum += vec4(c.xyz / c.w, 1.0);
        }
    }
    vec3 c_world = c_sum.xyz / max(c_sum.w, 1.0);
#endif
    vec2 l_c = triangle_barycentrics(c_world);
    vec3 l3 = max(vec3(1.0 - l_c.x - l_c.y, l_c), 0.0);
    l_c = l3.yz / max(l3.x + l3.y + l3.z, 1e-12);
    vec2 s = inverse(mat2(dFdxFine(l), dFdyFine(l))) * (l_c - l);
    // how far the pixel centre's point is from the covered one, in pixel footprints at the covered point
    float footprints = length(v_world - c_world) / max(length(c_world - uCameraPos) * uPixelRadians, 1e-30);
    bool finite = !any(isnan(s)) && !any(isinf(s)) && c_world_w.w > 0.0 && !isnan(footprints);
    // every varying moved by s, or by 0 (a + d 0 = a: the plain interpolant, bit for bit) where the
    // fragment keeps its pixel centre; the derivatives are taken in uniform control flow, as GLSL requires
    bool move = gl_SampleMaskIn[0] != (1 << gl_NumSamples) - 1 && !gl_HelperInvocation && finite
                && !(footprints <= MESH_MOVE_FOOTPRINTS);
    s = move ? s : vec2(0.0);
    mesh_world = MOVED(v_world, s);
    mesh_normal = MOVED(v_normal, s);
    mesh_uv = MOVED(v_uv, s);
    mesh_uv1 = MOVED(v_uv1, s);
    mesh_uv_ts = MOVED(v_uv_ts, s);
    mesh_tangent = MOVED(v_tangent, s);
    mesh_visibility = MOVED(v_visibility, s);
    mesh_blocked_sh0 = MOVED(v_blocked_sh0, s);
    mesh_blocked_sh1 = MOVED(v_blocked_sh1, s);
    mesh_blocked_sh2 = MOVED(v_blocked_sh2, s);
#ifdef DERMIS_VERTEX_CURVATURE
    mesh_curvature_v = MOVED(v_curvature, s);
#endif
#ifdef DERMIS_INTERREFLECTION
    mesh_bounce = MOVED(v_bounce, s);
#endif
}

#define v_world mesh_world
#define v_normal mesh_normal
#define v_uv mesh_uv
#define v_uv1 mesh_uv1
#define v_tangent mesh_tangent
#define v_uv_ts mesh_uv_ts
#define v_visibility mesh_visibility
#define v_blocked_sh0 mesh_blocked_sh0
#define v_blocked_sh1 mesh_blocked_sh1
#define v_blocked_sh2 mesh_blocked_sh2
#ifdef DERMIS_VERTEX_CURVATURE
#define v_curvature mesh_curvature_v
#endif
#ifdef DERMIS_INTERREFLECTION
#define v_bounce mesh_bounce
#endif
