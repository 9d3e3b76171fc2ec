"""Which part of tsd's final radiance carries the ear-fold comb that the pixel detail leaves (issue 12,
round 21, branch combs21).

tsd/gaussians.glsl's diffuse_irradiance_detail is swapped, as text at compile time, for one that
can draw ONE term of sum_k w_k (I_k(uv) + a_k R) (R = I_0(pixel) - I_1(uv)), or only its texture
part w_k I_k or only its detail part w_k a_k R; read the blurred levels with another reconstruction
filter (uRecon 1: the cubic B-spline from 4 bilinear taps, Sigg & Hadwiger, GPU Gems 2 ch. 20); or
write the final pass's texels per pixel, detail weight and texels per mm (uTermPart 3). Only the
final pass changes between the variants (the texture-space passes are cached on the lighting key),
so each variant is one final pass.

    PYTHONPATH=src python benchmarks/comb_terms.py groove      (the oblique V-groove of
        tests/test_tsd_fold_comb.py: the along-groove variation of each term, 128^2 against 512^2)
    PYTHONPATH=src python benchmarks/comb_terms.py head SCENE.toml --box X0 Y0 X1 Y1 [--size 768]
        [--npz OUT.npz] [--ref EARLIER.npz] [--base '{"uGate": [0.5, 1.0]}']
        (each term's difference between irradiance 1024 and 4096 over the box: rms and high-pass rms
        relative to the box's mean; every experiment's pixels > 10 display levels from irradiance
        4096; the texels per pixel and the detail's weight; diffuse only)
    PYTHONPATH=src python benchmarks/comb_terms.py report OUT.npz SCENE.toml

Round 21's numbers: benchmarks/RESULTS.md, "Round 21, branch combs21".
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))

DEBUG_DETAIL = r"""
uniform int uTermK;       // -1: every Gaussian; else only Gaussian k's term
uniform int uTermPart;    // 0: w_k (I_k + a_k R); 1: w_k I_k; 2: w_k a_k R; 3: (texels/px, weight, texels/mm)
uniform int uRecon;       // 0: bilinear reads of I_k; 1: cubic B-spline (4 bilinear taps)
uniform float uNyquistScale;  // a_k at uNyquistScale x the Nyquist frequency (1: main's)
uniform int uGateNorm;    // texels per pixel from the screen derivatives: 0 the larger column (main), 1 the smaller, 2 their geometric mean
uniform vec2 uGate;       // the detail fades out between these texels per pixel (main: 0.5, 1)
vec3 g_dbg;

vec4 bspline_read(sampler2D s, vec2 uv) {
    vec2 size = vec2(textureSize(s, 0));
    vec2 x = uv * size - 0.5;
    vec2 i = floor(x), f = x - i;
    vec2 f2 = f * f, f3 = f2 * f;
    vec2 w0 = (1.0 - 3.0 * f + 3.0 * f2 - f3) / 6.0, w1 = (4.0 - 6.0 * f2 + 3.0 * f3) / 6.0;
    vec2 w2 = (1.0 + 3.0 * f + 3.0 * f2 - 3.0 * f3) / 6.0, w3 = f3 / 6.0;
    vec2 g0 = w0 + w1, g1 = w2 + w3;
    vec2 h0 = (i - 0.5 + w1 / g0) / size, h1 = (i + 1.5 + w3 / g1) / size;
    return g0.y * (g0.x * texture(s, vec2(h0.x, h0.y)) + g1.x * texture(s, vec2(h1.x, h0.y)))
         + g1.y * (g0.x * texture(s, vec2(h0.x, h1.y)) + g1.x * texture(s, vec2(h1.x, h1.y)));
}

vec3 read_k(int k, vec2 uv) {
    vec4 t = uRecon == 1 ? bspline_read(uBlur[k], uv) : texture(uBlur[k], uv);
    return t.a > 0.0 ? t.rgb / t.a : vec3(0.0);
}

vec3 diffuse_irradiance_detail(vec2 uv, vec3 I0_pixel, float texels_per_mm, float weight) {
    vec3 I1 = read_k(0, uv);
    vec3 R = weight * (I0_pixel - I1);
    float q = 0.5 / (INV_PI * INV_PI) * texels_per_mm * texels_per_mm * uNyquistScale * uNyquistScale;
    vec3 E = vec3(0.0);
    for (int k = 0; k < MAX_GAUSSIANS; ++k) {
        if (k >= uGaussianCount) break;
        if (uTermK >= 0 && k != uTermK) continue;
        vec3 Ik = k == 0 ? I1 : read_k(k, uv);
        vec3 d = exp(-q * uVariances[k]) * R;
        E += uWeights[k] * (uTermPart == 1 ? Ik : uTermPart == 2 ? d : Ik + d);
    }
    return E;
}
"""

# the tree's own gate is replaced by uGate: (1, 2) since round 21 (main before it: 0.5, 1)
DEFAULTS = {"uTermK": -1, "uTermPart": 0, "uRecon": 0, "uNyquistScale": 1.0, "uGateNorm": 0, "uGate": (1.0, 2.0)}

# the experiments beside the per-term split: name -> uniforms
EXPERIMENTS = [("gate0.5-1", {"uGate": (0.5, 1.0)}), ("bspline", {"uRecon": 1}), ("nyq0.5", {"uNyquistScale": 0.5}), ("nyq0.75", {"uNyquistScale": 0.75}),
               ("bspline+nyq0.5", {"uRecon": 1, "uNyquistScale": 0.5}),
               ("gate0.75-1.5", {"uGate": (0.75, 1.5)}),
               ("gatemin", {"uGateNorm": 1, "uGate": (0.5, 1.0)}), ("gategeo", {"uGateNorm": 2, "uGate": (0.5, 1.0)}), ("gategeo1-2", {"uGateNorm": 2, "uGate": (1.0, 2.0)}),
               ("gatemin1-2", {"uGateNorm": 1, "uGate": (1.0, 2.0)}),
               ("gate2-4", {"uGate": (2.0, 4.0)}), ("bspline+gate0.5-1", {"uGate": (0.5, 1.0), "uRecon": 1})]


def _patch_source(src: str) -> str:
    if "vec3 diffuse_irradiance_detail(" not in src or "PIXEL_DETAIL" not in src:
        return src
    start = src.index("vec3 diffuse_irradiance_detail(")
    end = src.index("\n}\n", start) + 3
    src = src[:start] + DEBUG_DETAIL + src[end:]
    src = src.replace("    float texels_per_pixel = max(length(dFdx(v_uv_ts)), length(dFdy(v_uv_ts))) * uDetailTexels;",
                      "    float tpx_a = length(dFdx(v_uv_ts)) * uDetailTexels, tpx_b = length(dFdy(v_uv_ts)) * uDetailTexels;\n"
                      "    float texels_per_pixel = uGateNorm == 0 ? max(tpx_a, tpx_b) : uGateNorm == 1 ? min(tpx_a, tpx_b) : sqrt(tpx_a * tpx_b);")
    src = re.sub(r"\(1\.0 - smoothstep\([0-9.]+, [0-9.]+, texels_per_pixel\)\)", "(1.0 - smoothstep(uGate.x, uGate.y, texels_per_pixel))", src)
    src = src.replace("    float texels_per_mm = detail_texels_per_mm(uv_ts, gl_PrimitiveID);",
                      "    float texels_per_mm = detail_texels_per_mm(uv_ts, gl_PrimitiveID);\n"
                      "    g_dbg = vec3(texels_per_pixel, detail_weight, texels_per_mm);")
    src = src.replace("f_color = vec4(color, 1.0);", "f_color = uTermPart == 3 ? vec4(g_dbg, 1.0) : vec4(color, 1.0);")
    return src


@contextlib.contextmanager
def patched():
    import dermis.gl.shaders as sh

    orig = sh.load_shader_source

    def load(name, defines=None):
        s = orig(name, defines)
        return _patch_source(s) if name == "tsd/final.frag" else s

    sh.load_shader_source = load
    try:
        yield
    finally:
        sh.load_shader_source = orig


BASE = {}  # uniforms every variant starts from (head --base)


def set_debug(r, **values):
    """Write the debug uniforms into every PIXEL_DETAIL program tsd has compiled."""
    t = r.techniques["tsd"] if hasattr(r, "techniques") and "tsd" in r.techniques else r._techniques["tsd"]
    progs = [p for k, p in t._programs.items() if isinstance(k, tuple) and k[0] == "detail"]
    assert progs, "no PIXEL_DETAIL program compiled yet"
    v = {**DEFAULTS, **BASE, **values}
    for p in progs:
        for name, val in v.items():
            if p.get(name, None) is not None:
                p[name].value = val


def tsd_of(r):
    for attr in ("techniques", "_techniques"):
        d = getattr(r, attr, None)
        if isinstance(d, dict) and "tsd" in d:
            return d["tsd"]
    raise RuntimeError("no tsd technique on the renderer")


def variants(K):
    out = [("all", {}), ("trans", {"uTermK": 99})]
    for k in range(K):
        out += [(f"k{k + 1}", {"uTermK": k}), (f"k{k + 1}.I", {"uTermK": k, "uTermPart": 1}),
                (f"k{k + 1}.aR", {"uTermK": k, "uTermPart": 2})]
    return out


def groove(a):
    import moderngl  # noqa: F401
    from dermis.renderer import Renderer
    from dermis.techniques.shared import OutputMode
    import test_tsd_fold_comb as T

    rows = {}
    imgs = {}
    extra = [("bspline", {"uRecon": 1})] + [(f"nyq{s}", {"uNyquistScale": s}) for s in a.nyquist] + \
        [(f"bspline+nyq{s}", {"uRecon": 1, "uNyquistScale": s}) for s in a.nyquist]
    with patched():
        for S in (T.COARSE, T.FINE):
            with Renderer(T.oblique_groove_scene(), (T.SIZE, T.SIZE), samples=0, irradiance_size=S) as r:
                r.technique("tsd", translucency=False)
                r.render("tsd", output_mode=OutputMode.DIFFUSE)
                K = r.scene.profile.k
                for name, v in variants(K) + extra + [("dbg", {"uTermPart": 3})]:
                    set_debug(r, **v)
                    imgs[(S, name)] = r.render("tsd", output_mode=OutputMode.DIFFUSE)
                set_debug(r)
    peak = imgs[(T.FINE, "all")].reshape(-1, 3).max(axis=0)
    for name, _ in variants(K) + extra:
        ref = imgs[(T.FINE, name)]
        var = T.along_groove_variation(imgs[(T.COARSE, name)] - ref) / peak
        rows[name] = [round(float(x), 5) for x in var]
        print(f"{name:10s} {rows[name]}")
    d = imgs[(T.COARSE, "dbg")]
    print("coarse: texels/px median %.3f (px/texel %.2f), weight median %.3f, texels/mm %.3f" % (
        np.median(d[..., 0]), 1 / np.median(d[..., 0]), np.median(d[..., 1]), np.median(d[..., 2])))
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))


def head(a):
    import dermis
    from dermis.renderer import Renderer
    from dermis.reference.validate import display
    from dermis.techniques.shared import OutputMode

    sc = dermis.load_scene(a.scene)
    BASE.update(json.loads(a.base or "{}"))
    x0, y0, x1, y1 = a.box
    out = {}
    with patched():
        if a.ref:
            with np.load(a.ref) as z:
                out.update({(4096, k[5:]): z[k] for k in z.files if k.startswith("4096_")})
        for S in ((1024,) if a.ref else (1024, 4096)):
            with Renderer(sc, (a.size, a.size), irradiance_size=S) as r:
                if a.option:
                    r.technique("tsd", **{k: {"true": True, "false": False}[v] for k, v in (o.split("=") for o in a.option)})
                r.render("tsd", output_mode=OutputMode.DIFFUSE)
                K = r.scene.profile.k
                todo = variants(K) + [("dbg", {"uTermPart": 3})] + (EXPERIMENTS if S == 1024 else [])
                for name, v in todo:
                    set_debug(r, **v)
                    out[(S, name)] = r.render("tsd", output_mode=OutputMode.DIFFUSE)[y0:y1, x0:x1]
                    print(S, name, flush=True)
                set_debug(r)
    if a.npz:
        np.savez_compressed(a.npz, **{f"{S}_{n}": v for (S, n), v in out.items()})
    report(out, sc, a.scene)


def report(out, sc, label):
    from dermis.reference.validate import display

    def levels(img):
        return display(sc, np.clip(img, 0, None)) * 255.0

    full_ref = levels(out[(4096, "all")])
    ref_lin = out[(4096, "all")]
    for name in ["all"] + [n for n, _ in EXPERIMENTS]:
        if (1024, name) in out:
            d = np.abs(levels(out[(1024, name)]) - full_ref).max(-1)
            print(f"{label}: {name:20s} px > 10 levels {int((d > 10).sum()):4d}, > 5 {int((d > 5).sum()):4d}, max {d.max():.1f}")
    names = ["all", "trans"] + [n for n, _ in variants(6) if n.startswith("k")]
    for name in names:
        if (1024, name) not in out:
            continue
        if name == "trans":
            diff = out[(1024, name)] - out[(4096, name)]
        elif name.startswith("k"):  # the term alone: the translucency (in every term's image) taken off
            diff = (out[(1024, name)] - out[(1024, "trans")]) - (out[(4096, name)] - out[(4096, "trans")])
        else:
            diff = out[(1024, name)] - ref_lin
        # the comb: the difference minus its 5x5 box mean (high-pass), rms per channel, relative to the crop's mean
        from scipy.ndimage import uniform_filter
        hp = diff - np.stack([uniform_filter(diff[..., c], 5) for c in range(3)], -1)
        rel = np.sqrt((hp ** 2).mean(axis=(0, 1))) / ref_lin.mean(axis=(0, 1))
        rms = np.sqrt((diff ** 2).mean(axis=(0, 1))) / ref_lin.mean(axis=(0, 1))
        print(f"  {name:10s} rms(1024-4096)/mean {np.round(rms, 4)}  high-pass {np.round(rel, 4)}")
    dbg = out[(1024, "dbg")]
    print("  1024: texels/px median %.3f (px/texel %.2f; 10th pct %.2f), weight median %.2f, texels/mm median %.3f" % (
        np.median(dbg[..., 0]), 1 / np.median(dbg[..., 0]), 1 / np.percentile(dbg[..., 0], 90), np.median(dbg[..., 1]),
        np.median(dbg[..., 2])))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("groove")
    g.add_argument("--json")
    g.add_argument("--nyquist", type=float, nargs="*", default=[0.0, 0.25, 0.5, 0.75, 1.5])
    h = sub.add_parser("head")
    h.add_argument("scene")
    h.add_argument("--box", type=int, nargs=4, required=True)
    h.add_argument("--size", type=int, default=768)
    h.add_argument("--npz")
    h.add_argument("--option", action="append")
    h.add_argument("--ref", help="an earlier --npz: its irradiance-4096 images")
    h.add_argument("--base", help="JSON: uniforms every variant starts from, e.g. main's gate {\"uGate\": [0.5, 1.0]}")
    r = sub.add_parser("report")
    r.add_argument("npz")
    r.add_argument("scene")
    a = ap.parse_args(argv)
    if a.cmd == "report":
        import dermis
        with np.load(a.npz) as z:
            out = {(int(k.split("_", 1)[0]), k.split("_", 1)[1]): z[k] for k in z.files}
        report(out, dermis.load_scene(a.scene), a.scene)
        return
    {"groove": groove, "head": head}[a.cmd](a)


if __name__ == "__main__":
    main()
