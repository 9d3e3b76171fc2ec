// The baked subsurface transfer (dermis.subsurface_transfer; dermis/gl/subsurface_transfer.py) read at a
// texture-space uv: T_geo, the same-side light that a thin, curled sheet (the ear) carries beyond the
// flat profile, gathered per bake point into a grid (tsd/transfer_gather.vert). One read for every
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
