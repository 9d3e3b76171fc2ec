// The lights' sharp shadows (the specular's), computed once per texel in tsd's texture-space
// irradiance pass (tsd/irradiance.frag with SKIN_SHARP_SHADOWS, common/skin_irradiance.glsl) and
// read here by the final pass (with SHARP_SHADOW_READ) instead of a receiver solve and a
// shadow-map tap per light per screen sample (d'Eon & Luebke 2007, 14.5.2: the shadow is computed
// in the irradiance texture and reused for the specular).
// One RGBA8 target: x coverage, y z w the sharp shadows of lights 0, 1, 2, so scenes of at most
// 3 lights (dermis.techniques.tsd.STORED_SHARP_SHADOWS; for more it draws the per-sample programs:
// a second target would take the final pass past the 16 texture units every GL 4.5 has).
// The target is cleared to 0, so a lookup is the bilinear mean of the covered texels only (the
// sum of shadow x coverage over the sum of coverage): island borders never read the cleared gutter;
// with no covered texel under it (a sample just outside every island) the shadow is 1.

#ifdef SHARP_SHADOW_READ
uniform sampler2D uSharpShadow;
vec3 g_sharp_shadow;

// Fetch the stored sharp shadows at texture-space uv (once per fragment).
void load_sharp_shadows(vec2 uv) {
    vec4 t = texture(uSharpShadow, uv);
    g_sharp_shadow = t.x > 0.0 ? t.yzw / t.x : vec3(1.0);
}

// light i's (i < 3) sharp shadow at the uv given to load_sharp_shadows
float stored_sharp_shadow(int i) {
    return g_sharp_shadow[i];
}
#endif
