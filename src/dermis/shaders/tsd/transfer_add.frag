// Subsurface transfer, step 2: the grid of T_curl (tsd/transfer_gather.vert) read bilinearly at each
// texel of tsd's translucency target and added to it (additive blending; alpha 0 leaves the target's
// coverage as it was), so the final pass adds it to the diffused irradiance exactly as the light
// through thin parts: (sum_k w_k I_k + T + T_curl) albedo^(1-mix) / pi. Texels between bake points
// and the grid's edges blend towards 0 (no bake: no light added).
uniform sampler2D uTransfer;
uniform vec2 uTargetSize;
out vec4 f_add;

void main() {
    f_add = vec4(texture(uTransfer, gl_FragCoord.xy / uTargetSize).rgb, 0.0);
}
