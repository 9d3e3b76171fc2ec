// Interreflection, step 3: the per-vertex bounce irradiance E_b (tsd/bounce_gather.frag),
// interpolated over the triangles (tsd/uv_space.vert with INTERREFLECTION), added to the irradiance
// texture as the lights' is stored there, E_b albedo^mix (tsd/irradiance.frag), with additive
// blending (alpha 0: the coverage stays), before the dilation and the blur chain: the diffusion
// spreads the bounce light (and its Monte Carlo noise) as it does every other light.
// With BOUNCE_EXITANT it writes instead the light that bounce light sends on, rho T (T the per-vertex
// bounce irradiance, rho = albedo^1 the skin's total diffuse albedo, as tsd/bounce_exitant.frag's
// rho E), coverage 1 into a cleared target: the source of the next bounce's gather
// (dermis.gl.interreflection.BounceSeries), rho read from uRho: BOUNCE_RHO's raster of albedo_at
// alone, drawn once per material and layout.
#include "common/surface.glsl"
#include "common/albedo_mix.glsl"

uniform float uMix;
in vec2 v_uv;
#ifndef BOUNCE_RHO
in vec3 v_bounce;  // tsd/uv_space.vert with INTERREFLECTION
#endif
out vec4 f_irradiance;
#ifdef ALBEDO_MIX_TARGET
// albedo^mix as tsd/irradiance.frag wrote it at this texel (SKIN_ALBEDO_MIX_LOCATION): the same
// value as below without a second read of the albedo map (this pass rasterises the same layout into
// a target of the same size, so the fragment is that texel)
uniform sampler2D uAlbedoMix;
#endif
#ifdef BOUNCE_EXITANT
uniform sampler2D uRho;  // rho per texel of this raster's target (BOUNCE_RHO), rgba32f
#endif

void main() {
#if defined(BOUNCE_RHO)
    // rho alone, once per material and layout (dermis.gl.interreflection.BounceSeries): the orders'
    // rasters below read it back at their own texel instead of sampling the albedo map again
    f_irradiance = vec4(albedo_at(v_uv), 1.0);
#elif defined(BOUNCE_EXITANT)
    // the same raster at the same size as BOUNCE_RHO's: this fragment's texel holds the rho that
    // albedo_at(v_uv) gives here, bit for bit (same fragment, same derivatives)
    f_irradiance = vec4(max(v_bounce, vec3(0.0)) * texelFetch(uRho, ivec2(gl_FragCoord.xy), 0).rgb, 1.0);
#else
#ifdef ALBEDO_MIX_TARGET
    vec3 albedo_mix = texelFetch(uAlbedoMix, ivec2(gl_FragCoord.xy), 0).rgb;
#else
    vec3 albedo_mix = albedo_power(albedo_at(v_uv), uMix);
#endif
    f_irradiance = vec4(max(v_bounce, vec3(0.0)) * albedo_mix, 0.0);
#endif
}
