"""The procedural head's data: the ProceduralHead arrays, its parts, units and the constants the
geometry and the texture painter share (see the package docstring)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MM_PER_UNIT = 10.0
LABIOMENTAL_Y = -6.75  # height of the labio-mental fold (normal map), cm


def NASOLABIAL_X(y):
    """|x| of the naso-labial fold (normal map) at height y, cm."""
    t = np.clip((np.asarray(y, float) + 2.3) / -3.6, 0, 1)
    return 1.75 + 1.1 * t + 0.25 * t * t


PORE_SPACING_MM = 1.0
ATLAS_RESOLUTION = 1024  # texels per side the UV charts are packed for
ATLAS_PADDING_TEXELS = 6  # xatlas padding around every chart: >= 12 texels between charts at 1024^2
# Boxes (mesh units, (lo xyz), (hi xyz)) inside which the layout has no seam: xatlas alone cuts the nose's
# underside and nostrils off the face chart along the nose-lip crease, between the lit nose and the shadowed
# upper lip, where tsd's per-chart blurs then lose the red the nose scatters into the lip (issue 12, round 21
# seam21: the upper lip under the nose 0.908 of Cycles' red), and the face's chart ended on the cheeks; the
# charts reaching into a box are joined (dermis.geometry.parameterize.join_charts): here the face's, both
# sides' (chin to crown, ear to ear in front of the ears) and the nose underside's, one chart.
ATLAS_SEAMLESS_BOXES = (((-2.6, -5.0, 7.5), (2.6, 0.5, 20.0)),  # the nose, its nostrils and the upper lip
                        ((3.0, -4.0, 4.0), (6.0, 2.0, 20.0)),  # the cheeks: the face chart's sides
                        ((-6.0, -4.0, 4.0), (-3.0, 2.0, 20.0)))


@dataclass
class ProceduralHead:
    positions: np.ndarray  # (N, 3) float32, centimetres, y up, face toward +z
    normals: np.ndarray  # (N, 3) float32, unit, outward, smooth
    uvs: np.ndarray  # (N, 2) float32, v = 0 is the bottom row of the textures
    indices: np.ndarray  # (M, 3) uint32, counter-clockwise seen from outside
    albedo: np.ndarray  # (H, W, 3) float32 linear RGB in [0, 1], row 0 = top
    normal_map: np.ndarray  # (H, W, 3) float32 tangent space, n * 0.5 + 0.5, OpenGL (+y = +v)
    specular: np.ndarray  # (H, W) float32 in [0, 1]
    mm_per_unit: float = MM_PER_UNIT
    pore_spacing_mm: float = PORE_SPACING_MM
    landmarks: dict = field(default_factory=dict)  # name -> (3,) float32 point, scene units
    islands: np.ndarray | None = None  # (M,) int8 part of each triangle (see PARTS)
    texel_mm: float = 0.0  # mean millimetres per texel of the skin islands at this texture size


PARTS = ("ring", "top_cap", "bottom_cap", "left_ear_front", "left_ear_back", "right_ear_front", "right_ear_back")
ISLANDS = PARTS  # former name (the parts were the UV islands before the layout came from xatlas)
