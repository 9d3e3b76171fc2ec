// One tile of the view grids' box-sum targets (tsd/transfer_view_box.frag), an instance per tile that can
// hold a non-zero sum: a tile touching a bake point's box texels (dermis.gl.subsurface_transfer.
// SubsurfaceTransfer.view_box). The grids are 0 away from the bake points (the gather writes only their
// texels, a mipmap averages them), so the targets' other texels keep the 0 they were cleared to: on
// the head's 513^2 targets the tiles are ~12 % of the texels (round 23).
layout(location = 0) in vec2 in_tile;  // the tile's index per axis
uniform vec2 uBoxSize;  // the targets' texels per axis
uniform float uTileTexels;  // texels per tile side
void main() {
    // two triangles, (0,0) (1,0) (1,1) and (0,0) (1,1) (0,1)
    int i = gl_VertexID;
    vec2 corner = vec2(i == 1 || i == 2 || i == 4 ? 1.0 : 0.0, i == 2 || i == 4 || i == 5 ? 1.0 : 0.0);
    gl_Position = vec4((in_tile + corner) * uTileTexels / uBoxSize * 2.0 - 1.0, 0.0, 1.0);
}
