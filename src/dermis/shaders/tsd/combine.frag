// Texture-space view of the diffuse irradiance: sum_k w_k I_k(uv) (d'Eon & Luebke 2007, 14.4.4),
// for inspection and for the numeric tests (the final pass computes the same per pixel).
#include "tsd/gaussians.glsl"
in vec2 v_uv;
out vec4 f_color;
void main() {
    f_color = vec4(diffuse_irradiance(v_uv), 1.0);
}
