// Subsurface transfer, step 2: the grid of T_geo (tsd/transfer_gather.frag) read at each texel of
// tsd's translucency target (common/subsurface_transfer.glsl: the tent at the target's level, set by
// dermis/gl/subsurface_transfer.py) and added to it (additive blending; alpha 0 leaves the target's
// coverage as it was), so the final pass adds it to the diffused irradiance as it adds the light
// through thin parts: (sum_k w_k I_k + T + T_geo) albedo^(1-mix) / pi.
#include "common/subsurface_transfer.glsl"
uniform vec2 uTargetSize;
out vec4 f_add;

void main() {
    f_add = vec4(subsurface_transfer(gl_FragCoord.xy / uTargetSize), 0.0);
}
