// The bump terminator (Chiang, Li & Burley 2019, "Taming the Shadow Terminator", SIGGRAPH talk):
// a normal map tilts the shading normal N toward a light that grazes the smooth (interpolated)
// surface, so N.L stays large up to the smooth surface's horizon and then drops to 0 there in one
// step, and everywhere the map's detail (stubble, wrinkles) moves that step the terminator is a
// serrated, hard edge (the side scene's eye socket and lips at 768 px: issue 12; it is not the
// shadow map: it stays with cast_shadows off and goes with the normal map off). The bumps of a
// real surface shadow each other there instead. Their term: g, the light the smooth surface
// intercepts (Ns.L per unit area) over what the tilted facet alone would (N.L / Ns.N, its area per
// unit of the smooth surface being 1 / Ns.N), is the visible fraction of the facet; g >= 1 is
// fully lit, g <= 0 (the light below the smooth horizon) unlit, and in between the smoothstep-like
// cubic g + g^2 - g^3 (C1 at g = 1). A multiplier of the DIFFUSE light only, as Blender Cycles
// applies it (kernel/closure/bsdf.h, bump_shadowing_term, on closures labelled diffuse: the
// BSSRDF's entry included), so the offline reference that `dermis validate` scores against has it
// too. Ns: the smooth surface's unit normal (v_normal), N the normal-mapped one, L toward the light.
float bump_shadowing(vec3 Ns, vec3 N, vec3 L) {
    float ndl = dot(N, L);
    float den = ndl * dot(Ns, N);
    if (ndl <= 0.0 || den <= 0.0) return 0.0;  // the facet faces away (the callers skip it anyway)
    float g = dot(Ns, L) / den;
    if (g >= 1.0) return 1.0;
    if (g <= 0.0) return 0.0;
    return g * (1.0 + g - g * g);
}
