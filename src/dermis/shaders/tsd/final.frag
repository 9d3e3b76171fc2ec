// Final pass of texture-space diffusion (d'Eon & Luebke 2007, 14.4.4 and 14.5), in screen space:
// diffuse = (sum_k w_k I_k(uv) k(N.V) + translucency) * albedo^(1 - mix) / pi * (1 - rho_s a(N.V, m) / pi)
// (k: the skin's directional albedo, common/directional_albedo.glsl; k(N.L) weighted the irradiance).
// translucency holds the baked subsurface transfer's cosine-view mean; its view term (the transfer along
// this fragment's view less that mean, common/subsurface_transfer.glsl, round 22) is added beside it.
// specular = sum_lights E_i * sharp shadow * KS_Skin_Specular / pi, on pore-detailed normals.
// Radiance is physical (d'Eon's BRDFs carry no 1/pi; dermis divides both terms by pi).
#include "common/shadow.glsl"
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"
#include "common/environment.glsl"
#include "common/brdf.glsl"
#include "common/noise.glsl"
#include "common/energy.glsl"
#include "common/directional_albedo.glsl"
#ifdef SHARP_SHADOW_READ  // at most STORED_SHARP_SHADOWS lights: their shadows from the irradiance pass
#include "tsd/sharp_shadow.glsl"
#define SPECULAR_SHADOW(i, P, Ng) stored_sharp_shadow(i)
#endif
#ifdef PIXEL_DETAIL
#include "common/skin_irradiance.glsl"
#endif
#include "common/skin_specular.glsl"
#include "tsd/gaussians.glsl"
#include "tsd/triangle_uv.glsl"
// the baked transfer's view term only (its cosine part is in uTranslucency): uTransfer stays inactive
#include "common/subsurface_transfer.glsl"
#ifdef PIXEL_DETAIL_BOUNCE
// The bounce T per mesh vertex that tsd/bounce_splat.frag added to I_0 (dermis.techniques.tsd: its
// gather's or series' target copied into a buffer, vertex v at v) and the index buffer, as shader
// storage: the final pass already uses every one of the 16 guaranteed samplers.
layout(std430, binding = BOUNCE_BINDING) readonly buffer BouncePerVertex {
    vec4 bounce_per_vertex[];
};
layout(std430, binding = INDEX_BINDING) readonly buffer MeshIndices {
    uint mesh_indices[];
};

// T at texture-space uv of triangle ``primitive``, interpolated linearly in the layout as the
// splat's raster interpolates it (uv on the triangle: uv_on_triangle); clamped at 0 as the splat does
vec3 bounce_on_triangle(vec2 uv, int primitive) {
    int i = 3 * primitive;
    vec2 a = triangle_uv_ts[i], b = triangle_uv_ts[i + 1], c = triangle_uv_ts[i + 2];
    float area = cross2(b - a, c - a);
    vec3 w = area != 0.0 ? triangle_weights(uv, a, b, c) / area : vec3(1.0 / 3.0);
    vec3 T = w.x * bounce_per_vertex[mesh_indices[i]].rgb + w.y * bounce_per_vertex[mesh_indices[i + 1]].rgb
           + w.z * bounce_per_vertex[mesh_indices[i + 2]].rgb;
    return max(T, vec3(0.0));
}
#endif

uniform sampler2D uTranslucency;
uniform float uMix;
uniform float uDirectionalAlbedo;  // 1: the skin's directional albedo at exit (scene.directional_albedo), 0: Lambertian
uniform float uPoreScaleMm;
uniform float uPoreStrength;
uniform vec3 uCameraPos;
uniform int uOutputMode;  // OUTPUT_FULL, OUTPUT_DIFFUSE or OUTPUT_SPECULAR (dermis.techniques.shared.OutputMode)
#ifdef PIXEL_DETAIL
uniform float uDetailTexels;  // texels across I_1's texture (the chain's first level)
#endif
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec2 v_uv_ts;  // texture-space UVs: tsd's own textures; v_uv: the material maps
in vec4 v_tangent;
in vec4 v_visibility;  // (ambient occlusion, visible fraction RGB): common/environment.glsl
in vec3 v_blocked_sh0;  // the L2 SH of the directions the mesh blocks: the specular occlusion
in vec3 v_blocked_sh1;
in vec3 v_blocked_sh2;
out vec4 f_color;

#ifdef PIXEL_DETAIL
// The surface metric in the layout at each triangle's corners, (E, F, G, 0) = (|dP/du|^2, dP/du.dP/dv,
// |dP/dv|^2) in scene units^2 per uv^2, averaged over the triangles around each vertex
// (dermis.geometry.texture_space.corner_surface_metric; dermis.gl.resources.GpuScene.corner_metric)
layout(std430, binding = CORNER_METRIC_BINDING) readonly buffer CornerMetric {
    vec4 corner_metric[];  // 3 per triangle, in the index buffer's order
};

// I_1's texels per mm of surface at texture-space uv (on triangle ``primitive``), along the layout's
// coarsest surface direction: texels per uv unit / the larger singular value of dP/d(uv) (mm per uv
// unit), i.e. / sqrt of the metric's larger eigenvalue. The metric is the corners' vertex averages
// interpolated linearly over the triangle, so the density is continuous across the triangles' edges
// inside a chart. It was each triangle's own (from screen derivatives: constant per triangle), and
// where R is large (a shadow's edge) a 10-15 % step of it between neighbouring triangles moved
// sum_k w_k a_k R by a display level or more: a one-pixel dark dip along the finer triangle's edge
// (issue 12, round 21, dots21: front-key's concha at 768 px, (660, 397) 13 levels beside 17-19).
// 1e6 (no detail: every a_k below is 0) where the metric is 0 (a vertex of degenerate triangles only).
float detail_texels_per_mm(vec2 uv, int primitive) {
    int i = 3 * primitive;
    vec2 a = triangle_uv_ts[i], b = triangle_uv_ts[i + 1], c = triangle_uv_ts[i + 2];
    float area = cross2(b - a, c - a);
    vec3 w = area != 0.0 ? clamp(triangle_weights(uv, a, b, c) / area, 0.0, 1.0) : vec3(1.0 / 3.0);
    vec3 M = w.x * corner_metric[i].xyz + w.y * corner_metric[i + 1].xyz + w.z * corner_metric[i + 2].xyz;
    // the larger eigenvalue of [[E, F], [F, G]]
    float lmax = 0.5 * (M.x + M.z) + sqrt(max(0.25 * (M.x - M.z) * (M.x - M.z) + M.y * M.y, 0.0));
    return lmax > 0.0 ? uDetailTexels / (sqrt(lmax) * uMmPerUnit) : 1e6;
}
#endif


void main() {
    vec3 Ng = normalize(v_normal);
    vec3 normal_map_texel = texture(uNormalMap, normal_map_uv(v_uv)).xyz * 2.0 - 1.0;  // perturb_normal's
    vec3 N = tangent_to_world(v_normal, v_tangent, normal_map_texel);
    vec3 V = normalize(uCameraPos - v_world);
    float m = roughness_at(v_uv);
    float rho_s = specular_intensity(v_uv);
    vec3 Ns = pore_normal(N, v_world * uMmPerUnit, uPoreScaleMm, uPoreStrength);
    float ndv = clamp(dot(Ns, V), 0.0, 1.0);

    // tsd's own textures at a point of this triangle (an edge sample's pixel-centre UV can lie
    // texels off it, on lit skin elsewhere: tsd/triangle_uv.glsl)
    vec2 uv_ts = uv_on_triangle(v_uv_ts, gl_PrimitiveID);

    vec3 albedo = albedo_at(v_uv);
    // the directional albedo's c (common/directional_albedo.glsl), once: the exit's k(N.V) below and,
    // with PIXEL_DETAIL, the entry's k(N.L) of I_0 at the pixel (computed in the detail's branch as
    // well, it ran twice: ~4 CPU ms of front-key's 768 px on llvmpipe, round 24)
    vec3 c_dir = uDirectionalAlbedo * directional_c(albedo);
    // k(N.V) is the half-space's REFLECTION (dermis.profiles.directional_albedo): the light that
    // entered on this side; the light through a thin part (translucency) is left Lambertian
#ifdef SHARP_SHADOW_READ
    load_sharp_shadows(uv_ts);
#endif
#ifdef PIXEL_DETAIL
    // The detail's weight first (screen derivatives: in uniform control flow), then I_0 only where it
    // is > 0 (a GPU skips that for whole warps of a zoomed-out frame; llvmpipe runs it masked).
    // A sample whose pixel centre lies off its triangle (multisampling: an edge sample) has P and N
    // extrapolated off it as far as uv_ts was moved back; a triangle seen edge-on moves them by
    // texels per pixel (tsd/triangle_uv.glsl), lighting the sample as some other surface: its
    // detail fades out between 1 and 2 texels off (an ordinary edge sample is within ~0.5)
    float off = length((uv_ts - v_uv_ts) * uDetailTexels);
    // and only where a texel covers about a pixel or more (full detail up to 1 texel per pixel, none
    // from 2, along the screen direction with the most texels). The blurred textures are read once
    // per pixel, at its centre: where a texel covers about a pixel, the bilinear read's phase in
    // the texel grid drifts slowly from pixel to pixel, and an irradiance that turns within a texel
    // (an ear fold at the adaptive 1024^2) shows as a moire of stripes, which the per-pixel I_0
    // removes (issue 12, round 21: front-key's helix, texels per pixel 0.95 at the stripes, was
    // left to a gate that stopped at 1). From 2 texels per pixel on, a pixel centre samples the
    // texels at an unrelated phase each and I_0 at it (its maps read at the pixel's coarser mip
    // level) is no better a sample than the texture's
    float texels_per_pixel = max(length(dFdx(v_uv_ts)), length(dFdy(v_uv_ts))) * uDetailTexels;
    float detail_weight = (1.0 - smoothstep(1.0, 2.0, off)) * (1.0 - smoothstep(1.0, 2.0, texels_per_pixel));
    float texels_per_mm = detail_texels_per_mm(uv_ts, gl_PrimitiveID);
    vec3 I0_mix = vec3(0.0);  // I_0 albedo^mix at the pixel (unused where the weight is 0)
    if (detail_weight > 0.0) {
        // I_0 as tsd/irradiance.frag and tsd/bounce_splat.frag put it into the irradiance texture, but
        // at this pixel: (E_lights + E_ambient + E_bounce) albedo^mix, the lights' soft shadows as there
        // (below); P and N at the centroid of the pixel's covered samples, inside the triangle:
        // every interior edge pixel has a fragment whose centre lies off its triangle, and I_0 of the
        // attributes extrapolated there drew the mesh's edges as faint lines (+1-2 %) into the detail
        // (the maps' values are the pixel centre's: a few texels of the maps move nothing that shows,
        // each further filtered read costs llvmpipe ~10 % of this pass)
        vec3 P_c = interpolateAtCentroid(v_world);
        vec3 n_c = interpolateAtCentroid(v_normal);
        vec3 Ng_c = normalize(n_c);
        vec3 N_c = tangent_to_world(n_c, interpolateAtCentroid(v_tangent), normal_map_texel);
        // the lights' soft (PCF) shadows at P_c, as the irradiance pass has them per texel, evaluated
        // here everywhere. Not only inside the stored sharp shadow's bilinear band (a texel each side of
        // its edge) with its 0 or 1 elsewhere: the PCF's penumbra on the surface is often wider than
        // that band (a light at grazing incidence, a coarse shadow map), and I_0 then stepped to full
        // shadow (or light) where the texture's levels hold a partial one, which the full detail drew
        // as single dark pixels along shadow edges (issue 12, round 21, dots21: front-key's nose
        // shadow (399, 525), stored sharp 0.00 against the PCF's 0.28: green 51 levels, irradiance
        // 4096 106; tests/test_tsd_pixel_detail.py's penumbra test)
        vec3 I0 = skin_lights_directional(P_c, Ng_c, N_c, rho_s, m, c_dir);
        I0 += skin_ambient(N_c, Ng_c, rho_s, m, interpolateAtCentroid(v_visibility));
#ifdef PIXEL_DETAIL_BOUNCE
        I0 += bounce_on_triangle(uv_ts, gl_PrimitiveID);
#endif
        I0_mix = I0 * albedo_power(albedo, uMix);
    }
    // outside the branch: its texture reads take implicit derivatives
    vec3 Ed = diffuse_irradiance_detail(uv_ts, I0_mix, texels_per_mm, detail_weight);
#else
    vec3 Ed = diffuse_irradiance(uv_ts);
#endif
    vec3 E = Ed * directional_factor(c_dir, ndv)
           + texture(uTranslucency, uv_ts).rgb + subsurface_transfer_view(uv_ts, V, Ng);
    vec3 diffuse = E * albedo_power(albedo, 1.0 - uMix) * INV_PI * energy_transmitted(rho_s, ndv, m);

    vec3 spec = skin_specular_radiance(v_world, Ng, Ns, V, m, rho_s, uSpecularTables, v_visibility,
                                       v_blocked_sh0, v_blocked_sh1, v_blocked_sh2);

    vec3 color = uOutputMode == OUTPUT_DIFFUSE ? diffuse : uOutputMode == OUTPUT_SPECULAR ? spec : diffuse + spec;
    f_color = vec4(color, 1.0);
}
