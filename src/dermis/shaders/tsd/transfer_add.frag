// Subsurface transfer, step 2: the grid of T_geo (tsd/transfer_gather.vert) read at each texel of
// tsd's translucency target and added to it (additive blending; alpha 0 leaves the target's coverage
// as it was), so the final pass adds it to the diffused irradiance as it adds the light through thin
// parts: (sum_k w_k I_k + T + T_geo) albedo^(1-mix) / pi.
// Read with the tent (1 2 1)^2 over the grid's texels at the level whose texels are at least the
// target's (its mipmaps where the target is coarser): the bake points are independent Monte Carlo
// estimates about 1 mm apart, and T_geo varies with the sheet's thickness and curvature over
// millimetres, so a 1-texel tent (sigma 0.7 texel) takes their noise down ~2.5x and not the signal.
// Texels between bake points and the grid's edges blend towards 0 (no bake: nothing added).
uniform sampler2D uTransfer;
uniform vec2 uTargetSize;
out vec4 f_add;

void main() {
    vec2 grid = vec2(textureSize(uTransfer, 0));
    float lod = max(0.0, log2(max(grid.x / uTargetSize.x, grid.y / uTargetSize.y)));
    float level = ceil(lod - 1e-4);
    vec2 texel = exp2(level) / grid;
    vec2 uv = gl_FragCoord.xy / uTargetSize;
    // the (1 2 1)^2 / 16 tent as four bilinear reads half a texel off each centre: a bilinear read
    // at +-0.5 texel averages two neighbours, so the four reads' mean is the nine texels' tent
    // (exact where uv is a texel centre of this level, as it is when the grid is a power of two of
    // the target; tsd/translucency_tent.frag does the same)
    vec3 sum = vec3(0.0);
    for (int dy = -1; dy <= 1; dy += 2) {
        for (int dx = -1; dx <= 1; dx += 2) {
            sum += textureLod(uTransfer, uv + 0.5 * vec2(dx, dy) * texel, level).rgb;
        }
    }
    f_add = vec4(0.25 * sum, 0.0);
}
