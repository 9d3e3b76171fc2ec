// Non-skin surfaces in the shadow atlas (vertex shader: common/mesh.vert): they write depth, so
// they shadow the skin and each other, with alphaMode MASK cut as in the shading; in the
// translucent shadow map they write w = 0, "no skin here": light that a prop stops is not carried
// through the tissue behind it (shadow/shadow.frag writes w >= 1 for skin).
#include "metallic_roughness/material.glsl"
in vec2 v_uv;
out vec4 f_aux;
void main() {
    mr_base_color(v_uv);  // discards below a MASK cutoff
    f_aux = vec4(0.0);
}
