"""Precomputed subsurface transfer for a rigid mesh's thin, curled parts (issue 12: the back-lit ear).

Light that enters the lit, curled rim of an ear and crosses 2-3 mm of tissue around the curl to a
point on the same side: short through the tissue, long along the surface. Texture-space diffusion
spreads irradiance with a profile of the distance ALONG the surface (its UV blurs), and its
translucency pass carries the opposite face along -N or the light; neither carries this path.

Here the transport of the mesh's own geometry is precomputed, light-independently, by the physical
skin random walk (dermis.reference.random_walk) and gathered at run time from the irradiance map
tsd already renders: precomputed radiance transfer with subsurface scattering (Sloan, Kautz & Snyder
2002 / Sloan et al. 2003; Wang, Tran & Gong 2005, "All-frequency interactive relighting of
translucent objects with single and multiple scattering"), the transfer between surface points
sampled by the adjoint walk thanks to the BSSRDF's reciprocity (Jensen et al. 2001).

* :mod:`dermis.subsurface_transfer.bake`: the bake (numpy + Embree, no GL).
* :mod:`dermis.subsurface_transfer.store`: the baked data on disk, found by the mesh's content.
"""
