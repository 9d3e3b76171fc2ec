"""Precomputed subsurface transfer for a rigid mesh's thin, curled parts (issue 12: the back-lit ear).

Texture-space diffusion spreads irradiance with the profile of a FLAT semi-infinite medium at the
distance along the surface, and its translucency pass carries the opposite face along -N or the
light. In an ear's thin, curled sheet the transport on the same side differs from the flat one: the
sheet guides light sideways (light that a thick medium scatters back from depth meets the far face
and is partly reflected there: less light within ~1 mm, more beyond), and a curled rim brings light
entering around the curl. That difference, the geometry's excess over the flat medium, is what is
baked here (benchmarks/RESULTS.md, round 10: measured on the head's ear, tsd's blur equals the
flat profile integrated at the geodesic distance, while the skin walk gives ~25% more same-side
light where the ear's translucency is small).

Here the transport of the mesh's own geometry is precomputed, light-independently, by the physical
skin random walk (dermis.reference.random_walk) and gathered at run time from the irradiance map
tsd already renders: precomputed radiance transfer with subsurface scattering (Sloan, Kautz & Snyder
2002 / Sloan et al. 2003; Wang, Tran & Gong 2005, "All-frequency interactive relighting of
translucent objects with single and multiple scattering"), the transfer between surface points
sampled by the adjoint walk thanks to the BSSRDF's reciprocity (Jensen et al. 2001).

Round 22 (view22): the transfer depends on the view. The same walks also give each tap a first-order
view term (the walk's tally against its refracted start direction, Fresnel at entry; bake.view_basis),
which the readers evaluate at the fragment's view (common/subsurface_transfer.glsl).

* :mod:`dermis.subsurface_transfer.bake`: the bake (numpy + Embree, no GL).
* :mod:`dermis.subsurface_transfer.store`: the baked data on disk, found by the mesh's content.
"""
