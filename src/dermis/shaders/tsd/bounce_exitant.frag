// Interreflection, step 1 (dermis/geometry/interreflection.py): the light leaving the skin, times pi,
// in texture space: rho E = I_0 albedo^(1 - mix), I_0 = E albedo^mix the irradiance texture
// (tsd/irradiance.frag), read at this texel. Coverage 1 (the pass rasterises the mesh's layout into
// a cleared target), so the 2x2 reductions that follow (tsd/downsample.frag) give it premultiplied.
//
// Skin's exitant radiance is the diffused irradiance, albedo^(1-mix) sum_k w_k I_k / pi, not the
// local rho E / pi: the higher orders read this light at ~2 mm texels (BOUNCE_TEXEL_MM), a box as
// wide as the profile's widest Gaussians; the one bounce at ~1 mm (FIRST_ORDER_FINER_LEVELS in
// dermis/gl/interreflection.py), as Cycles does through dermis's bridge: skin reached after a
// diffuse bounce is a plain diffuse BSDF there, no second random walk (BOUNCE_ORDERS' docstring).
// The blur chain runs after the bounce is added: the bounce is blurred too. Bounce light is low-frequency (Dachsbacher & Stamminger
// 2005, "Reflective Shadow Maps", gather from a low-resolution map of the directly lit surface;
// Ritschel et al. 2012, STAR sec. 3), so the coarse level loses nothing the bounce shows.
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"

uniform sampler2D uIrradiance;  // I_0 (tsd/irradiance.frag), this pass's size
uniform float uMix;
in vec2 v_uv;
out vec4 f_exitant;

void main() {
    vec3 I0 = texelFetch(uIrradiance, ivec2(gl_FragCoord.xy), 0).rgb;
    f_exitant = vec4(I0 * albedo_power(albedo_at(v_uv), 1.0 - uMix), 1.0);
}
