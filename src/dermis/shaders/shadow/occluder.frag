// Non-skin surfaces in the shadow atlas (vertex shader: common/mesh.vert): they write depth, so
// they shadow the skin and each other, with alphaMode MASK cut as in the shading (the only reason
// this pass has a fragment shader; the atlas has no colour attachment).
#include "metallic_roughness/material.glsl"
in vec2 v_uv;
void main() {
    mr_base_color(v_uv);  // discards below a MASK cutoff
}
