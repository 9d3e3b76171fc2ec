"""tsd's gathered irradiance (the texture the subsurface transfer's gather reads; premultiplied rgba, row 0 = v 0) for
scenes, saved as OUT/irr_<scene>.npy (round 22, branch denoise22; for benchmarks/denoise_truth.py --irradiance and
denoise_mechanism.py). A 256 px frame, irradiance 1024 (the texture-space map does not depend on the frame size).

    PYTHONPATH=src python benchmarks/capture_irradiance.py OUT back-ears front-key
"""
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    import dermis
    import dermis.gl.subsurface_transfer as G
    from dermis.renderer import Renderer

    out, scenes = Path(argv[0]), argv[1:]
    cap = {}
    orig = G.SubsurfaceTransfer.gather

    def gather(self, irradiance, mipmaps=True):  # the texture as the gather receives it
        dt = {"f2": np.float16, "f4": np.float32}[irradiance.dtype]
        cap["irr"] = np.frombuffer(irradiance.read(), dt).astype(np.float32).reshape(irradiance.size[1], irradiance.size[0], 4).copy()
        return orig(self, irradiance, mipmaps)

    G.SubsurfaceTransfer.gather = gather
    out.mkdir(parents=True, exist_ok=True)
    for s in scenes:
        sc = dermis.load_scene(str(REPO / "examples" / "reference" / f"{s}.toml"))
        with Renderer(sc, (256, 256), irradiance_size=1024) as r:
            r.render("tsd")
        np.save(out / f"irr_{s}.npy", cap["irr"])
        print(s, cap["irr"].shape)
    return 0


if __name__ == "__main__":
    sys.exit(main())
