"""The offline reference: dermis's skin model integrated directly over the surface (CPU, no GL).

Texture-space diffusion and the other real-time techniques approximate one surface integral,
L_diffuse(x) = integral R(|x - y|) E(y) dA(y). This package computes it for the same scene,
lights, profile and specular, so that each technique's error can be measured (``dermis validate``).

Modules, one concept each:

* ``sampling``  - the surface cut into area-weighted lattice cells; attributes and material maps
                  looked up exactly as the shaders do (bilinear, clamp-to-edge, v up).
* ``shading``   - lights, the irradiance that scatters (exact shadows) and the specular.
* ``integrate`` - the profile integral by 3-D distance (KD-tree, cutoff at 1e-4 of each peak).
* ``render``    - the image: visible points by ray casting (dermis.geometry.raycast, Embree),
                  sub-pixel resolve (``render_reference``).
* ``validate``  - FLIP, SSIM and relative RMSE of the techniques against it, with error attribution.
* ``cli``       - ``dermis reference`` and ``dermis validate``.
"""

__all__ = ["ReferenceResult", "render_reference"]


def __getattr__(name):
    """render_reference and ReferenceResult on first use (PEP 562): ``dermis`` registers this package's
    commands at every start, and importing render (scipy.spatial, numba) cost each CLI process ~0.5 s."""
    if name in __all__:
        from dermis.reference import render

        return getattr(render, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
