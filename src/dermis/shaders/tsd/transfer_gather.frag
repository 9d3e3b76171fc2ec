// Subsurface transfer, step 1: the point's sum (tsd/transfer_gather.vert) into the bake's grid.
flat in vec3 v_transfer;
out vec4 f_transfer;

void main() {
    f_transfer = vec4(v_transfer, 1.0);
}
