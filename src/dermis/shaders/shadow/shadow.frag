// Writes depth (to the depth attachment) and, for translucency, the surface's (u, v), its
// distance to the light in mm and 1 + its cosine to the light (d'Eon & Luebke 2007, sec. 14.5.3,
// "translucent shadow maps"). The cosine is the entry side's N.L: the irradiance that enters
// where light crosses a thin part is E max(N.L, 0) there, not at the exit (which faces away).
// w >= 1 marks coverage (the atlas is cleared to 0).
#include "common/lights.glsl"
uniform int uLight;
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
out vec4 f_aux;
float light_distance_mm_here(vec3 P) {
    int type = int(uLightPosType[uLight].w + 0.5);
    if (type == LIGHT_DIRECTIONAL) return dot(P - uLightPosType[uLight].xyz, uLightDir[uLight].xyz) * uMmPerUnit;
    return length(P - uLightPosType[uLight].xyz) * uMmPerUnit;
}
void main() {
    vec3 L;
    light_incident(uLight, v_world, L);
    float cos_entry = clamp(dot(normalize(v_normal), L), 0.0, 1.0);
    f_aux = vec4(v_uv, light_distance_mm_here(v_world), 1.0 + cos_entry);
}
