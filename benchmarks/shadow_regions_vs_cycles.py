"""Why every technique trails Cycles' no-SSS control in the nose-shadow penumbra (front-key) and
the eyelids (side): the control includes interreflected light and a pixel-area film filter; the
techniques have neither. Cycles renders (nospec, pore_strength 0) at SIZE^2: SSS (two seeds, the
reference), plain diffuse (the validation's control) and plain diffuse with max_bounces = 0
(direct light only: the same delta sun and ray-traced shadows as the control, no bounce light);
then lambert / tsd / ssss, at SIZE^2 and supersampled 8x with a box filter, scored per region
with dermis.blender.validate's masks and metrics. Stored under OUT (resumed when present).

    PYTHONPATH=src python benchmarks/shadow_regions_vs_cycles.py [OUT] [SIZE] [SPP]   (bpy's venv)
"""
import os
import sys
from pathlib import Path

import numpy as np

import dermis
from dermis.blender.render import render_cycles
from dermis.blender.validate import CyclesAccumulation, region_masks
from dermis.reference.validate import metrics
from dermis.renderer import Renderer

REPO = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/shadow_regions")
N = int(sys.argv[2]) if len(sys.argv) > 2 else 64
SPP = int(sys.argv[3]) if len(sys.argv) > 3 else 256
SS = 8
out.mkdir(parents=True, exist_ok=True)
for stem in ("front-key", "side"):
    sc = dermis.load_scene(REPO / "examples" / "reference" / f"{stem}.toml")
    sc.material.pore_strength = 0.0
    sc.material.rho_s = 0.0
    acc = CyclesAccumulation(sc, (N, N), sss=True, specular=False, path=out / f"{stem}_sss.npz")
    if acc.spp < SPP:
        acc.add(SPP - acc.spp)
    ctl = CyclesAccumulation(sc, (N, N), streams=1, sss=False, specular=False, seed_base=1 << 20,
                             path=out / f"{stem}_nosss.npz")
    if ctl.spp < SPP:
        ctl.add(SPP - ctl.spp)
    direct_path = out / f"{stem}_direct_{N}_{SPP}.npy"
    if not direct_path.is_file():
        d, _ = render_cycles(sc, (N, N), spp=SPP, seed=7, sss=False, specular=False, alpha=True, max_bounces=0)
        np.save(direct_path, d)
    a, b = acc.image(0), acc.image(1)
    skin = (a[..., 3] >= 0.999) & (b[..., 3] >= 0.999)
    ref = 0.5 * (a + b)[..., :3]
    reg = region_masks(sc, (N, N), skin)
    imgs = {"Cycles no SSS (control)": ctl.image(0)[..., :3],
            "Cycles no SSS, direct only": np.load(direct_path)[..., :3]}
    for size, tag in ((N, ""), (N * SS, f", {SS}x supersampled")):
        with Renderer(sc, (size, size)) as r:
            for t in ("lambert", "tsd", "ssss"):
                img = r.render(t)
                imgs[t + tag] = img.reshape(N, SS, N, SS, 3).mean((1, 3)) if size != N else img
    print(f"== {stem} {N}x{N}, {SPP} spp, load {os.getloadavg()[0]:.1f}")
    for name, img in imgs.items():
        fmap = metrics(sc, ref, img, skin)[1]
        cols = []
        for rn in ("nose_shadow_penumbra", "eyelids", "shadow_edge"):
            m = reg.get(rn)
            if m is not None and m.sum() >= 8:
                ratio = img[m].mean(0) / ref[m].mean(0)
                cols.append(f"{rn} {fmap[m].mean():.4f} (R/G/B {ratio[0]:.3f}/{ratio[1]:.3f}/{ratio[2]:.3f})")
        print(f"  {name:40s} " + "  ".join(cols), flush=True)
