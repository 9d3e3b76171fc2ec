"""Where tsd's red rim along the nose shadow comes from (issue 12, round 6): a close-up of the
front-key nose wing's cast shadow on the cheek (40 mm across, same eye as the scene, nospec,
rho_s 0), rendered by the techniques, dermis's surface-integral reference (the same profile,
ray-cast hard shadows, exact integral) and optionally Cycles (SSS, with and without bounce light:
max_bounces 0), then mean radiance per band of distance from the shadow edge (bands from lambert's
shadow: lit if red > 0.3). Variants isolate the irradiance texel (irradiance 4096) and the PCF
penumbra (shadow_softness 0). Renders are cached under OUT.

    PYTHONPATH=src python benchmarks/shadow_edge_rim.py [OUT] [SIZE] [--cycles SPP]   (bpy's venv for --cycles)
"""
import math
import os
import sys
from pathlib import Path

import numpy as np

import dermis
from dermis.renderer import Renderer

REPO = Path(__file__).resolve().parent.parent
FIELD_MM = 40.0
TARGET_MM = (14.0, -14.0, -18.0)  # about the nose tip: the nose wing's cast shadow on the +x cheek


def closeup():
    sc = dermis.load_scene(REPO / "examples" / "reference" / "front-key.toml")
    sc.material.rho_s = 0.0
    pos = np.asarray(sc.mesh.positions, np.float64)
    tip = pos[np.argmax(pos[:, 2])]
    tgt = tip + np.asarray(TARGET_MM) / sc.mm_per_unit
    d = np.linalg.norm(tgt - np.asarray(sc.camera.position, np.float64)) * sc.mm_per_unit
    sc.camera.target = tuple(tgt)
    sc.camera.fov_deg = math.degrees(2 * math.atan(0.5 * FIELD_MM / d))
    return sc


def cached(path: Path, make):
    if not path.is_file():
        np.save(path, np.asarray(make(), np.float32))
    return np.load(path)


def main(argv):
    args = [a for a in argv if not a.startswith("--")]
    out = Path(args[0] if args else "out/shadow_edge_rim")
    n = int(args[1]) if len(args) > 1 else 192
    cyc_spp = int(argv[argv.index("--cycles") + 1]) if "--cycles" in argv else 0
    out.mkdir(parents=True, exist_ok=True)
    imgs = {}
    for tag, soft, irr in (("", None, 1024), (", irradiance 4096", None, 4096), (", softness 0 + irr. 4096", 0.0, 4096)):
        def render(t, soft=soft, irr=irr):
            sc = closeup()
            if soft is not None:
                for L in sc.lights:
                    L.shadow_softness = soft
            with Renderer(sc, (n, n), irradiance_size=irr) as r:
                return r.render(t)
        names = ("tsd", "ssss", "preintegrated", "lambert") if not tag else ("tsd",)
        for t in names:
            imgs[t + tag] = cached(out / f"{t}{tag.replace(' ', '_').replace(',', '').replace('+', '')}_{n}.npy", lambda t=t: render(t))

    def reference():
        from dermis.reference.render import render_reference
        return render_reference(closeup(), (n, n), spp=4, progress=False).image
    imgs["reference"] = cached(out / f"reference_{n}.npy", reference)
    if cyc_spp:
        from dermis.blender.render import render_cycles
        for tag, mb in (("Cycles", None), ("Cycles direct (max_bounces 0)", 0)):
            imgs[tag] = cached(out / f"cycles_{mb}_{n}_{cyc_spp}.npy", lambda mb=mb: render_cycles(
                closeup(), (n, n), spp=cyc_spp, seed=1, sss=True, specular=False, threads=1, max_bounces=mb)[0][..., :3])
    from scipy.ndimage import distance_transform_edt

    lam = imgs["lambert"][..., 0]
    roi = np.zeros_like(lam, bool)
    roi[n // 12: n // 2, 5 * n // 12: 5 * n // 6] = True  # the cheek beside the nose wing
    lit = lam > 0.3
    mm = FIELD_MM / n
    dsh, dlit = distance_transform_edt(~lit) * mm, distance_transform_edt(lit) * mm
    dark = lam < 0.05
    bands = [("lit 1-2 mm", (dlit > 1) & (dlit <= 2)), ("lit 0-1 mm", (dlit > 0) & (dlit <= 1)),
             ("shadow 0-0.5 mm", (dsh > 0) & (dsh <= 0.5) & dark), ("shadow 0.5-1 mm", (dsh > 0.5) & (dsh <= 1) & dark),
             ("shadow 1-2 mm", (dsh > 1) & (dsh <= 2) & dark), ("shadow 2-3 mm", (dsh > 2) & (dsh <= 3) & dark)]
    print(f"front-key nose-wing shadow, {n}^2 over {FIELD_MM:.0f} mm, nospec; mean R/G/B per band; load {os.getloadavg()[0]:.1f}")
    print("| band | pixels | " + " | ".join(imgs) + " |")
    print("|---|---|" + "---|" * len(imgs))
    for name, m in bands:
        m = m & roi
        print(f"| {name} | {int(m.sum())} | " + " | ".join("{:.3f}/{:.3f}/{:.3f}".format(*im[m].mean(0)) for im in imgs.values()) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
