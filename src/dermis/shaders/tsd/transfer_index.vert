// Subsurface transfer, step 0 (once per bake, dermis/gl/subsurface_transfer.py): one GL point per bake
// point p at its texel of the bake's grid (its texture-space uv), writing p (tsd/transfer_index.frag)
// into an r32i map of the grid (-1 where no point lies). Where points share a texel the last one drawn
// stays, as it did when the gather itself drew the points (rounds 10-23). The gather
// (tsd/transfer_gather.frag) then runs per texel of that map, drawn as tiles: on llvmpipe a point costs
// ~0.3 us of setup and rasterisation and the vertex stage runs on the calling thread alone (round 24).
layout(location = 0) in vec2 in_uv;
flat out int v_point;

void main() {
    v_point = gl_VertexID;
    gl_Position = vec4(in_uv * 2.0 - 1.0, 0.0, 1.0);
}
