"""The built-in default scene's geometry and textures: a procedural head-and-neck bust.

Modules, one concept each: ``model`` (the arrays, parts and constants), ``implicit`` (the implicit
surface and ray casting against it), ``meshing`` (ring grid and caps), ``ears`` (thin shells),
``painter`` (textures), ``assembly`` (parts + xatlas layout + landmarks, ``build_default_head``).

Everything here is generated from code (numpy/scipy only, no files, no GL), deterministically for
a given seed, so that ``dermis render`` with no arguments gives a meaningful skin image anywhere.

Geometry (scene units are centimetres, ``mm_per_unit = 10``; y up, the face looks toward +z, the
subject's left is +x):

* The head and neck are one smooth implicit surface: smooth unions of ellipsoids / capsules
  (cranium, forehead, cheeks, jaw, chin, lips, nose, brow ridge, sterno-cleido-mastoid muscles,
  neck) minus smooth subtractions (eye sockets, nostrils), with closed eyelids
  (eyeball spheres) and a flat cut at the bottom of the neck.  It is star-shaped around a centre
  ``C`` inside the head, so it is meshed by casting rays from ``C``.
* Meshing avoids poles and grazing rays: a *ring* grid (columns at fixed azimuth, denser on the
  face; rows re-sampled per column at equal weighted arc length, denser on the face) from the
  hairline down to the neck cut, a *top cap* and a flat *bottom cap* triangulated (Delaunay) in a
  normalised disc whose boundary is exactly the ring's first / last row.
* The ears are separate, genuinely thin closed shells (about 2.6 mm thick flap, up to ~4 mm at
  the helix rim and lobe, rounded edges) whose front edge is buried in the side of the head (they
  interpenetrate it, like a sculpt base mesh), so they transmit light when back-lit.
* Concave parts: eye sockets (the closed lids lie ~7 mm and the inner corners ~13 mm inside the
  convex hull), nostrils (tunnels toward ``C``, ~6 mm deeper than their rim).

UV layout (unique, for texture-space diffusion): xatlas charts (dermis.geometry.atlas: charts,
least-squares conformal parameterisation, packing) of the welded surface, packed for 1024^2 with
``ATLAS_PADDING_TEXELS`` of padding around every chart (>= 12 texels between charts), all charts
at one texel density (~0.5 mm of skin per texel at 1024^2). Charts may be mirrored (tangent
handedness w = -1 there); the normal map is encoded in the frame the renderer rebuilds either way.
``islands`` labels each triangle with its part (``PARTS``: the ring of the head and neck, the top
cap, the bottom cut, the front / back sheet of each ear), which the texture painter uses as masks.
The gutters of every texture are filled with the value of the nearest chart texel (dilation), so
bilinear filtering and blurs never pick up black.

Textures (row 0 = top of the image, i.e. texel (row, col) is at u = (col + .5) / W,
v = 1 - (row + .5) / H; v = 0 is the bottom row, the OpenGL convention used by the UVs):

* ``albedo``: linear RGB, fair skin (mean ~ (0.45, 0.25, 0.17)) with low-frequency melanin and
  redness blotches (3-D noise, so they are continuous across UV seams), redness on cheeks, nose
  and ears, freckles (~1 mm spots, mostly on nose and cheeks), eyebrows, closed eyelids with a
  dark lash line, darker nostrils, red lips (~(0.45, 0.12, 0.10)).
* ``normal_map``: tangent-space (OpenGL: +x along +u, +y along +v, encoded n * 0.5 + 0.5) from a
  height field in millimetres: pores (dimples ~0.06 mm deep on a jittered grid
  ``pore_spacing_mm`` = 1.0 mm apart, ~100 per cm^2 -- the density of visible facial pores; at
  1024^2 a texel is ~0.52 mm, so finer spacings could not be represented), band-limited
  micro-relief (0.3-1 mm), forehead lines, crow's feet, lip lines, the closed-eyelid groove, the
  mouth line, labio-mental and naso-labial folds.  The perturbation is expressed in the frame
  the renderer rebuilds (dermis.scene.tangents: T = dP/du orthogonalised against N,
  B = cross(N, T), w = +1), exactly, using each triangle's UV Jacobian.
* ``specular``: intensity in [0, 1]: oily T-zone (forehead, nose, chin) and lips brighter,
  eyebrows and pores duller.

Landmarks (scene units): head_centre, crown, forehead, left/right_eye (closed lid),
left/right_eye_inner_socket, nose_tip, left/right_nostril (bottom of the nostril),
lips (mouth line), upper_lip, lower_lip, left/right_cheek, chin, neck (front),
left/right_ear (middle of the visible ear flap, inside it), left/right_ear_root (inside the head).

``build_default_head`` is cached (``functools.lru_cache``); the arrays it returns are read-only,
copy them before modifying.  Building takes about 1-2 s at 1024^2 (geometry ~1 s, textures
~1 s).
"""

from dermis.scene.procedural_head.assembly import build_default_head
from dermis.scene.procedural_head.model import (ISLANDS, LABIOMENTAL_Y, MM_PER_UNIT, NASOLABIAL_X, PARTS,
                                                PORE_SPACING_MM, ProceduralHead)

__all__ = ["ISLANDS", "LABIOMENTAL_Y", "MM_PER_UNIT", "NASOLABIAL_X", "PARTS", "PORE_SPACING_MM", "ProceduralHead",
           "build_default_head"]
