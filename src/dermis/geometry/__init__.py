"""Geometry on triangle meshes, built on maintained libraries.

* ``raycast``       - ray-vs-mesh queries through Embree (``embreex``): closest hits, any-hit
                      occlusion, batched hit distances (camera and shadow rays of the reference
                      renderer; ambient occlusion, bent normals and thickness bakes).
* ``rasterize``     - a triangle rasteriser in UV space (which triangle covers each texel, its
                      barycentrics, how many triangles cover it): texture painting, overlap tests.
* ``thickness``     - the tissue's thickness behind every texel along -N and where it ends (tsd's
                      light through thin parts), by ray casting.
* ``interreflection`` - the first hits of cosine-weighted rays from every vertex: tsd's one diffuse
                      bounce between skin surfaces, by ray casting.
* ``atlas``         - texture-space UV atlases from xatlas (charts, parameterisation, packing with
                      gutters), cached on disk by the mesh's content hash.
* ``hull``          - the points of a cloud that can hold the maximum of a linear function (its
                      convex hull's): what fitting a view or a shadow map to a mesh needs.
* ``texture_space`` - the UV set texture-space diffusion works in: the mesh's own when unique,
                      else one generated with xatlas, beside the asset's UVs for its textures.
"""
