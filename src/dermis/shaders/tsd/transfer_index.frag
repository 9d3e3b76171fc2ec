// Subsurface transfer, step 0: the bake point drawn at this texel of the grid (tsd/transfer_index.vert).
flat in int v_point;
layout(location = 0) out int f_point;

void main() {
    f_point = v_point;
}
