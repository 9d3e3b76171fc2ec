// The lights' sharp shadows (the specular's), computed once per texel in tsd's texture-space
// irradiance pass (tsd/irradiance.frag, common/skin_irradiance.glsl) and read here by the final
// pass instead of a receiver solve and a shadow-map tap per light per screen sample (d'Eon &
// Luebke 2007, 14.5.2: the shadow is computed in the irradiance texture and reused for the
// specular). Channels, flat over the SHARP_SHADOW_TARGETS RGBA8 targets: 0 coverage, 1 + i light
// i (0 outside the mesh's UV islands, cleared). A lookup is the bilinear mean of the covered texels
// only (the sum of shadow x coverage over the sum of coverage), so island borders never read the
// cleared gutter; with no covered texel under it (a sample just outside every island) it is 1.
const int SHARP_SHADOW_TARGETS = (MAX_LIGHTS + 1 + 3) / 4;

#ifdef SHARP_SHADOW_READ
uniform sampler2D uSharpShadow[SHARP_SHADOW_TARGETS];
float g_sharp_shadow[4 * SHARP_SHADOW_TARGETS];

// Fetch every light's stored sharp shadow at texture-space uv (once per fragment).
void load_sharp_shadows(vec2 uv, int light_count) {
    vec4 t0 = texture(uSharpShadow[0], uv);
    float inv = t0.x > 0.0 ? 1.0 / t0.x : 0.0;
    for (int t = 0; t < SHARP_SHADOW_TARGETS; ++t) {
        // a target holding no used light is not read (on llvmpipe the fetch runs masked anyway)
        vec4 v = t == 0 ? t0 : (4 * t <= light_count ? texture(uSharpShadow[t], uv) : vec4(0.0));
        for (int c = 0; c < 4; ++c)
            g_sharp_shadow[4 * t + c] = inv > 0.0 ? v[c] * inv : 1.0;
    }
}

// light i's sharp shadow at the uv given to load_sharp_shadows
float stored_sharp_shadow(int i) {
    return g_sharp_shadow[i + 1];
}
#endif
