"""The ``dermis`` command line, run as a real subprocess.

Bad input of every kind must give exit status 2, exactly one non-empty line on stderr that names
the file (or option) and the problem, no traceback, and no output file (neither --out nor a temp
file beside it). The good path writes PNG, EXR and --stats JSON that agree with each other.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the helpers below, under any import mode

from test_loaders import gltf_document, png_bytes, small_grid, texture_u8, write_glb, write_gltf  # noqa: E402
from test_output import aces_narkowicz, read_exr, srgb_encode  # noqa: E402

DERMIS_SCRIPT = Path(sys.executable).parent / "dermis"

SPHERE_TOML = """\
[mesh]
builtin = "sphere"

[[lights]]
type = "directional"
direction = [0.3, -0.4, -1.0]
intensity = 3.0
"""


def run_cli(args, cwd, timeout=120):
    return subprocess.run([sys.executable, "-m", "dermis.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)


@pytest.fixture(scope="module")
def bad_inputs(tmp_path_factory):
    """Every bad input, written once: name -> (scene argument, extra args, tokens the message needs)."""
    d = tmp_path_factory.mktemp("bad")
    pos, uv, idx = small_grid()
    cases = {}

    cases["missing mesh"] = (d / "missing.glb", [], ["missing.glb", "not found"])

    rng = np.random.default_rng(11)
    (d / "garbage.glb").write_bytes(rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
    cases["corrupt glb (garbage)"] = (d / "garbage.glb", [], ["garbage.glb", "glTF"])
    good = d / "good.glb"
    doc, binary = gltf_document(pos, uv, idx)
    write_glb(good, doc, binary)
    raw = good.read_bytes()
    (d / "truncated.glb").write_bytes(raw[:40] + rng.integers(0, 256, 64, dtype=np.uint8).tobytes())
    cases["corrupt glb (valid magic, garbage body)"] = (d / "truncated.glb", [], ["truncated.glb", "glTF"])

    (d / "garbage.obj").write_bytes(rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
    cases["corrupt OBJ (garbage)"] = (d / "garbage.obj", [], ["garbage.obj", "OBJ"])

    doc, binary = gltf_document(pos, None, idx)
    cases["glTF without TEXCOORD_0"] = (write_gltf(d / "nouv.gltf", doc, binary), [], ["nouv.gltf", "UV"])
    obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n"
    (d / "nouv.obj").write_text(obj)
    cases["OBJ without vt"] = (d / "nouv.obj", [], ["nouv.obj", "UV"])

    bad = pos.copy()
    bad[3, 1] = np.nan
    doc, binary = gltf_document(bad, uv, idx)
    for k in ("min", "max"):
        doc["accessors"][0].pop(k)
    cases["NaN positions"] = (write_gltf(d / "nan.gltf", doc, binary), [], ["nan.gltf", "NaN"])

    (d / "asset").mkdir()
    (d / "outside.png").write_bytes(png_bytes(texture_u8()))
    doc, binary = gltf_document(pos, uv, idx, image=("uri", "../outside.png"))
    cases["image URI outside the folder"] = (write_gltf(d / "asset" / "escape.gltf", doc, binary), [],
                                             ["escape.gltf", "outside", "refused"])

    # 9000 x 9000 > 8192^2 = MAX_IMAGE_PIXELS; a 1-bit PNG of zeros is ~10 kB on disk
    Image.new("1", (9000, 9000)).save(d / "big.png")
    (d / "big.toml").write_text('[mesh]\nbuiltin = "sphere"\n\n[material]\nalbedo = "big.png"\n')
    cases["oversized image (TOML)"] = (d / "big.toml", [], ["big.png", "9000x9000", "limit"])
    (d / "asset2").mkdir()
    (d / "asset2" / "big.png").write_bytes((d / "big.png").read_bytes())
    doc, binary = gltf_document(pos, uv, idx, image=("uri", "big.png"))
    cases["oversized image (glTF)"] = (write_gltf(d / "asset2" / "bigtex.gltf", doc, binary), [],
                                       ["big.png", "9000x9000", "limit"])

    sphere = d / "sphere.toml"
    sphere.write_text(SPHERE_TOML)
    cases["size too large"] = (sphere, ["--size", "100000x100000"], ["--size", "100000x100000", "limit"])
    cases["size zero"] = (sphere, ["--size", "0x10"], ["--size", "0x10", "at least"])
    cases["size not a number"] = (sphere, ["--size", "big"], ["--size", "big"])
    cases["unknown technique"] = (sphere, ["--technique", "nosuch"], ["nosuch", "unknown technique"])

    (d / "typo.toml").write_text('[mesh]\nbuiltin = "sphere"\n\n[material]\nroughnes = 0.3\n')
    cases["TOML key typo"] = (d / "typo.toml", [], ["typo.toml", "roughnes", "[material]"])
    (d / "typo_top.toml").write_text('[mesh]\nbuiltin = "sphere"\n\n[camra]\nfov_deg = 30.0\n')
    cases["TOML table typo"] = (d / "typo_top.toml", [], ["typo_top.toml", "camra"])
    return d, cases


# "glTF without TEXCOORD_0" and "OBJ without vt" render since meshes without UVs get generated
# ones (tests/test_texture_space_uvs.py checks they render with tsd)
BAD_CASES = ["missing mesh", "corrupt glb (garbage)", "corrupt glb (valid magic, garbage body)", "corrupt OBJ (garbage)",
             "NaN positions", "image URI outside the folder",
             "oversized image (TOML)", "oversized image (glTF)", "size too large", "size zero",
             "size not a number", "unknown technique", "TOML key typo", "TOML table typo"]


@pytest.mark.parametrize("case", BAD_CASES)
def test_cli_bad_input_one_line_exit_2_no_output(bad_inputs, case, tmp_path):
    _, cases = bad_inputs
    scene, extra, tokens = cases[case]
    out = tmp_path / "out"
    out.mkdir()
    res = run_cli(["render", scene, *extra, "--out", out / "render.png", "--exr", out / "render.exr",
                   "--stats", out / "stats.json"], cwd=tmp_path)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2, (res.returncode, res.stderr)
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.stderr + res.stdout
    msg = lines[0]
    assert msg.startswith("dermis: error: ")
    for tok in tokens:
        assert tok in msg, (tok, msg)
    assert list(out.iterdir()) == [], "an output (or temp) file was left behind"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no default out/ either


def test_cli_output_folder_missing(bad_inputs, tmp_path):
    d, _ = bad_inputs
    res = run_cli(["render", d / "sphere.toml", "--out", tmp_path / "nope" / "r.png"], cwd=tmp_path)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert "Traceback" not in res.stderr
    assert "nope" in lines[0] and "does not exist" in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_oversized_image_refused_before_decoding(bad_inputs, monkeypatch):
    """In process: the pixel limit is checked on the header; decoding is never started."""
    from PIL import ImageFile

    from dermis.errors import DermisError
    from dermis.images import MAX_IMAGE_PIXELS, read_image

    assert MAX_IMAGE_PIXELS == 8192 * 8192
    d, _ = bad_inputs

    def no_decoding(self, *a, **k):
        raise AssertionError("the image was decoded")

    monkeypatch.setattr(ImageFile.ImageFile, "load", no_decoding)
    with pytest.raises(DermisError, match="over the limit"):
        read_image(d / "big.png", srgb=True)


# ---------------------------------------------------------------------------------------------
# 10. --stats and info


def test_cli_render_writes_png_exr_and_stats(tmp_path, gl_ctx):
    (tmp_path / "sphere.toml").write_text(SPHERE_TOML)
    out = tmp_path / "o"
    out.mkdir()
    res = run_cli(["render", "sphere.toml", "-t", "lambert", "--size", "64x48", "--samples", "0",
                   "--out", out / "r.png", "--exr", out / "r.exr", "--stats", out / "s.json"], cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "Traceback" not in res.stderr
    assert sorted(p.name for p in out.iterdir()) == ["r.exr", "r.png", "s.json"]  # no temp files left

    stats = json.loads((out / "s.json").read_text())
    assert stats["technique"] == "lambert"
    assert stats["size"] == [64, 48]
    assert stats["renderer"] == gl_ctx.info["GL_RENDERER"]
    passes = stats["passes_ms"]
    assert {"shadow", "lambert"} <= set(passes)
    assert all(np.isfinite(v) and v > 0 for v in passes.values())
    assert np.isfinite(stats["frame_ms"])
    assert stats["frame_ms"] >= sum(passes.values()) * 0.999  # the passes run inside the frame

    (w, h), ch = read_exr(out / "r.exr")
    assert (w, h) == (64, 48)
    hdr = ch["RGB"] if "RGB" in ch else np.stack([ch["R"], ch["G"], ch["B"]], -1)
    assert np.isfinite(hdr).all() and hdr.max() > 0.05
    with Image.open(out / "r.png") as im:
        assert im.size == (64, 48)
        png = np.asarray(im.convert("RGB")).astype(int)
    # the PNG is the EXR through the scene's output transform (exposure 0, ACES), computed here
    expected = np.floor(srgb_encode(aces_narkowicz(hdr.astype(np.float64))) * 255 + 0.5).astype(int)
    assert np.abs(png - expected).max() <= 1


def test_cli_info_prints_the_renderer(gl_ctx):
    assert DERMIS_SCRIPT.is_file(), f"console script not installed at {DERMIS_SCRIPT}"
    renderer = gl_ctx.info["GL_RENDERER"]
    res = subprocess.run([str(DERMIS_SCRIPT), "info"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert renderer in res.stdout
    res = subprocess.run([str(DERMIS_SCRIPT), "info", "--json"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert data["renderer"] == renderer
    assert data["version_code"] >= 450
    assert "lambert" in data["techniques"]


def test_cli_texture_sizes_auto_follow_the_view_and_a_number_wins(tmp_path, gl_ctx):
    """--irradiance-size / --shadow-size auto: the sizes dermis.adaptive_resolution picks for the
    view (a close-up: more than the Renderer's fixed 1024 / 2048); a number given wins; neither
    given: auto too (issue 12: resolution from the head's size on screen, `dermis render` included)."""
    import dermis
    from dermis.adaptive_resolution import adaptive_sizes

    close = SPHERE_TOML + "\n[camera]\nposition = [0.0, 0.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nfov_deg = 1.0\n"
    (tmp_path / "close.toml").write_text(close)
    want = adaptive_sizes(dermis.load_scene(tmp_path / "close.toml"), (64, 48))
    assert want[0] > 1024 and want[1] > 2048, want  # the close-up's sizes differ from the defaults

    def sizes(*flags):
        res = run_cli(["render", "close.toml", "-t", "lambert", "--size", "64x48", "--samples", "0",
                       "--out", "r.png", "--stats", "s.json", *flags], cwd=tmp_path)
        assert res.returncode == 0, res.stderr
        stats = json.loads((tmp_path / "s.json").read_text())
        return stats["irradiance_size"], stats["shadow_size"]

    assert sizes("--irradiance-size", "auto", "--shadow-size", "AUTO") == want
    assert sizes("--irradiance-size", "512", "--shadow-size", "1024") == (512, 1024)
    assert sizes() == want
    res = run_cli(["render", "close.toml", "--irradiance-size", "big", "--out", "r.png"], cwd=tmp_path)
    assert res.returncode == 2 and res.stderr.strip() == "dermis: error: --irradiance-size: expected an integer or 'auto', got 'big'"
