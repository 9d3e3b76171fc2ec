// A run of square tiles along x of a target, an instance per run (dermis.gl.subsurface_transfer: tile_runs;
// one quad per run, not per tile: fewer triangles for llvmpipe to set up, the same texels), for the passes
// of the baked transfer that write only near its points and leave the rest as it is:
// - the gather (tsd/transfer_gather.frag): the tiles holding a bake point's texel of the grid;
// - the view grids' box sums (tsd/transfer_view_box.frag): the tiles that can hold a non-zero sum, those
//   touching a bake point's box texels (SubsurfaceTransfer.view_box). The grids are 0 away from the bake
//   points (the gather writes only their texels, a mipmap averages them), so the targets' other texels
//   keep the 0 they were cleared to: on the head's 513^2 targets the tiles are ~12 % of the texels (round 23);
// - the add into tsd's translucency target (tsd/transfer_add.frag): the tiles whose tent can read a non-zero
//   grid texel (add_tiles); elsewhere it would add 0 (round 24).
layout(location = 0) in vec3 in_tile;  // the run's first tile's index per axis, its length in tiles
uniform vec2 uBoxSize;  // the target's texels per axis
uniform float uTileTexels;  // texels per tile side
void main() {
    // two triangles, (0,0) (1,0) (1,1) and (0,0) (1,1) (0,1)
    int i = gl_VertexID;
    vec2 corner = vec2(i == 1 || i == 2 || i == 4 ? 1.0 : 0.0, i == 2 || i == 4 || i == 5 ? 1.0 : 0.0);
    gl_Position = vec4((in_tile.xy + corner * vec2(in_tile.z, 1.0)) * uTileTexels / uBoxSize * 2.0 - 1.0, 0.0, 1.0);
}
