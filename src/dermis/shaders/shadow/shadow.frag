// Writes depth (to the depth attachment) and, for translucency, the surface's (u, v) and its
// distance to the light in mm (d'Eon & Luebke 2007, sec. 14.5.3, "translucent shadow maps").
#include "common/lights.glsl"
uniform int uLight;
in vec3 v_world;
in vec2 v_uv;
out vec4 f_aux;
float light_distance_mm_here(vec3 P) {
    int type = int(uLightPosType[uLight].w + 0.5);
    if (type == LIGHT_DIRECTIONAL) return dot(P - uLightPosType[uLight].xyz, uLightDir[uLight].xyz) * uMmPerUnit;
    return length(P - uLightPosType[uLight].xyz) * uMmPerUnit;
}
void main() {
    f_aux = vec4(v_uv, light_distance_mm_here(v_world), 1.0);
}
