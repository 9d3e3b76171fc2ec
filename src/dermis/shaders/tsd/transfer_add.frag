// Subsurface transfer, step 2: the grid of T_geo (tsd/transfer_gather.vert) read at each texel of
// tsd's translucency target and added to it (additive blending; alpha 0 leaves the target's coverage
// as it was), so the final pass adds it to the diffused irradiance as it adds the light through thin
// parts: (sum_k w_k I_k + T + T_geo) albedo^(1-mix) / pi. Trilinear: where the target is coarser
// than the grid, the mip level of its texel's footprint (from the derivatives of the pass's uv).
// Texels between bake points and the grid's edges blend towards 0 (no bake: nothing added).
uniform sampler2D uTransfer;
uniform vec2 uTargetSize;
out vec4 f_add;

void main() {
    f_add = vec4(texture(uTransfer, gl_FragCoord.xy / uTargetSize).rgb, 0.0);
}
