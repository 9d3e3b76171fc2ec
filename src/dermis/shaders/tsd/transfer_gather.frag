// Subsurface transfer, step 1: the point's sums (tsd/transfer_gather.vert) into the bake's grids:
// attachment 0 the cosine views' T_geo, 1-3 the view term's (G_x, G_y, G_z, c) . I of the red, green,
// blue channels (common/subsurface_transfer.glsl: subsurface_transfer_view).
flat in vec3 v_transfer;
flat in vec4 v_view_r;
flat in vec4 v_view_g;
flat in vec4 v_view_b;
layout(location = 0) out vec4 f_transfer;
layout(location = 1) out vec4 f_view_r;
layout(location = 2) out vec4 f_view_g;
layout(location = 3) out vec4 f_view_b;

void main() {
    f_transfer = vec4(v_transfer, 1.0);
    f_view_r = v_view_r;
    f_view_g = v_view_g;
    f_view_b = v_view_b;
}
