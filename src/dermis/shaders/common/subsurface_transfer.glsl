// The baked subsurface transfer (dermis.subsurface_transfer; dermis/gl/subsurface_transfer.py) read at a
// texture-space uv: T_geo, the same-side light that a thin, curled sheet (the ear) carries beyond the
// flat profile, gathered per bake point into a grid (tsd/transfer_gather.frag). One read for every
// technique: tsd adds it into its translucency target (tsd/transfer_add.frag), ssss's final pass and
// preintegrated read it at the fragment's texture-space uv (the light leaving the skin, after any blur,
// as tsd adds it after its blurs).
// Read with the tent (1 2 1)^2 over the grid's texels at level uTransferLevel (its mipmaps where the
// reader is coarser than the grid; the level whose texels are at least the target's: tsd's translucency
// target, S / 2 for irradiance size S, for all three): the bake points are independent Monte Carlo
// estimates about 1 mm apart, and T_geo varies with the sheet's thickness and curvature over
// millimetres, so a 1-texel tent (sigma 0.7 texel) takes their noise down ~2.5x and not the signal.
// Texels between bake points and the grid's edges blend towards 0 (no bake: nothing added).
// uTransferLevel < 0: no bake for this scene (or translucency off), 0 is returned.
uniform sampler2D uTransfer;
uniform float uTransferLevel;

vec3 subsurface_transfer(vec2 uv) {
    if (uTransferLevel < 0.0) return vec3(0.0);
    vec2 texel = exp2(uTransferLevel) / vec2(textureSize(uTransfer, 0));
    // the (1 2 1)^2 / 16 tent as four bilinear reads half a texel off each centre: a bilinear read
    // at +-0.5 texel averages two neighbours, so the four reads' mean is the nine texels' tent
    // (exact where uv is a texel centre of this level, as it is when the grid is a power of two of
    // the target; tsd/translucency_tent.frag does the same)
    vec3 sum = vec3(0.0);
    for (int dy = -1; dy <= 1; dy += 2) {
        for (int dx = -1; dx <= 1; dx += 2) {
            sum += textureLod(uTransfer, uv + 0.5 * vec2(dx, dy) * texel, uTransferLevel).rgb;
        }
    }
    return 0.25 * sum;
}

// The view-dependent transfer (round 22, issue 12: the bake's cosine views against the camera's ray:
// +0.11-0.13 E0 red too much at front-key's mouth line, 1.3x too little at the back-lit ear; benchmarks/
// RESULTS.md round 21 taps21). The bake's view term (dermis.subsurface_transfer.bake.view_basis): a
// walk along the view v enters with the Fresnel transmittance 1 - F(v) and what it carries is linear in
// its refracted direction r(v), so the transfer seen along v is
//     T(v) = (1 - F(v)) (G . r(v) + c)      per channel, (G, c) gathered with the irradiance at the taps
// (tsd/transfer_gather.frag: one rgba32f grid per channel, G in the mesh's frame). Its mean over the
// bake's cosine views would be the grid above (uTransfer) in expectation, but bake.smooth_view (the 2.5 mm
// averaging the noisy view term needs) hands each neighbour's taps to the point's nearest taps, so only ~20 %
// of the own tap's weight stays on it and T's mean drifts from uTransfer (the back-lit helix rim 1.33-1.41x,
// lid creases 0.78x; uTransfer itself agrees with fresh walks within 0.89-1.04: RESULTS.md round 22 rim22,
// denoise22). So subsurface_transfer_view returns T(v) less T's OWN mean over the bake's cosine views,
// a0 c + a1 G . N (uTransferViewMean; bake.view_mean_constants): the view's deviation alone, which a reader
// adds to what it adds of uTransfer. Read as images (the same tent at uTransferLevel,
// clamped at the edges as the sampler): tsd's final pass already uses all 16 guaranteed samplers.
// The images hold the grids' 2 x 2 box sums at uTransferLevel (tsd/transfer_view_box.frag, one texel wider per
// axis than the level: texel k sums the level's texels k - 1 and k per axis, clamped), so the tent's 3 x 3
// texels are 2 x 2 loads per grid: 12 image loads, not 27 (the loads were ~80 % of this term's cost on
// llvmpipe, about 50 of tsd's ~590 ms single-threaded final pass at 768 px; round 23).
// Units 1-3 (0 is common/mesh_varyings.glsl's triangle frames): dermis.gl.subsurface_transfer.VIEW_IMAGE.
layout(binding = 1, rgba32f) readonly uniform image2D uTransferViewR;
layout(binding = 2, rgba32f) readonly uniform image2D uTransferViewG;
layout(binding = 3, rgba32f) readonly uniform image2D uTransferViewB;
uniform float uTransferIndex;  // the bake's medium's refractive index against air (its meta "index"); < 0: no view term
uniform vec2 uTransferViewMean;  // (a0, a1): the cosine-view means of 1 - F(v) and (1 - F(v)) r(v) . N (bake.view_mean_constants)

// the unpolarised Fresnel reflectance of a smooth dielectric entered from air at cos_i (the walk's
// dermis.reference.random_walk.fresnel_unpolarised, its rule for the entry)
float transfer_fresnel(float cos_i, float eta) {
    cos_i = clamp(cos_i, 0.0, 1.0);
    float sin_t = sqrt(max(0.0, 1.0 - cos_i * cos_i)) / eta;
    if (sin_t >= 1.0 || cos_i < 1e-9) return 1.0;
    float cos_t = sqrt(max(0.0, 1.0 - sin_t * sin_t));
    float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    float rp = (cos_t - eta * cos_i) / (cos_t + eta * cos_i);
    return 0.5 * (rs * rs + rp * rp);
}

// V: unit direction from the surface to the eye; N: the unit geometric normal (the bake's is the
// facet's: the interpolated one differs by a few degrees on the head's mesh)
vec3 subsurface_transfer_view(vec2 uv, vec3 V, vec3 N) {
    if (uTransferLevel < 0.0 || uTransferIndex < 0.0) return vec3(0.0);
    ivec2 last = imageSize(uTransferViewR) - 1;  // the box images' last texel = the level's size
    // the tent of subsurface_transfer as texel weights: its reads at +-0.5 texel, each bilinear, are
    // (1 - f) / 2, 1 / 2, f / 2 on the texels i0, i0 + 1, i0 + 2 per axis (i0 = floor(p - 0.5)), i.e.
    // (1 - f) / 2 on the box sum of i0 and i0 + 1 (box texel i0 + 1) and f / 2 on that of i0 + 1 and i0 + 2
    vec2 p = uv * vec2(last) - 0.5;
    vec2 q = p - 0.5;
    ivec2 i0 = ivec2(floor(q)) + 1;
    vec2 f = q - floor(q);
    vec2 wx = vec2(1.0 - f.x, f.x) * 0.5, wy = vec2(1.0 - f.y, f.y) * 0.5;
    vec4 r = vec4(0.0), g = vec4(0.0), b = vec4(0.0);
    for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 2; ++x) {
            ivec2 t = clamp(i0 + ivec2(x, y), ivec2(0), last);
            float w = wx[x] * wy[y];
            r += w * imageLoad(uTransferViewR, t);
            g += w * imageLoad(uTransferViewG, t);
            b += w * imageLoad(uTransferViewB, t);
        }
    }
    float eta = uTransferIndex;
    float cos_v = dot(N, V);
    float T = 1.0 - transfer_fresnel(cos_v, eta);
    vec3 rv = refract(-V, N, 1.0 / eta);  // the walk's refracted view (0 past total reflection: T is 0 there)
    vec3 seen = T * vec3(dot(r.xyz, rv) + r.w, dot(g.xyz, rv) + g.w, dot(b.xyz, rv) + b.w);
    vec3 mean = uTransferViewMean.x * vec3(r.w, g.w, b.w)
              + uTransferViewMean.y * vec3(dot(r.xyz, N), dot(g.xyz, N), dot(b.xyz, N));
    return seen - mean;
}
