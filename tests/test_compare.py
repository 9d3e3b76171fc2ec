"""``dermis compare``: the labelled side-by-side sheet and its JSON, run as a real
subprocess like the rest of the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
from PIL import Image

SPHERE_TOML = """\
[scene]
mm_per_unit = 10.0

[mesh]
builtin = "sphere"

[[lights]]
type = "directional"
direction = [0.6, -0.4, -0.7]
intensity = 3.0

[camera]
position = [0.0, 0.0, 4.0]
fov_deg = 40.0
"""


def run_cli(args, cwd, timeout=300):
    return subprocess.run([sys.executable, "-m", "dermis.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)


def test_compare_writes_a_labelled_sheet_and_timings(tmp_path, gl_ctx):
    """Four techniques at 64x48: the sheet holds one tile per technique, in order, each exactly the
    image the API renders (output transform applied), with bands for the labels and times; the
    JSON has every technique's frame time and passes, and ratios to lambert."""
    import dermis
    from dermis.output import output_transform
    from dermis.renderer import Renderer

    (tmp_path / "sphere.toml").write_text(SPHERE_TOML)
    names = ["tsd", "ssss", "preintegrated", "lambert"]
    res = run_cli(["compare", "sphere.toml", "--techniques", ",".join(names), "--size", "64x48",
                   "--irradiance-size", "128", "--out", "sheet.png", "--json", "t.json"], tmp_path)
    assert res.returncode == 0, res.stderr
    sheet = np.asarray(Image.open(tmp_path / "sheet.png").convert("RGB")).astype(np.int16)
    data = json.loads((tmp_path / "t.json").read_text())
    assert list(data["techniques"]) == names and data["size"] == [64, 48]
    for n in names:
        t = data["techniques"][n]
        assert t["frame_ms"] > 0 and t["passes_ms"] and t["passes_run"]
        assert abs(data["ratio_to_lambert"][n] - t["frame_ms"] / data["techniques"]["lambert"]["frame_ms"]) < 1e-9
    assert "tsd_blur" in data["techniques"]["tsd"]["passes_run"]  # timed frames re-ran the cached passes
    assert "shadow" in data["techniques"]["lambert"]["passes_run"]
    # the tiles: find each image by matching the API's render of the same technique
    sc = dermis.load_scene(tmp_path / "sphere.toml")
    with Renderer(sc, (64, 48), ctx=gl_ctx, samples=4, irradiance_size=128) as r:
        tiles = [np.round(output_transform(r.render(n)) * 255).astype(np.int16) for n in names]
    H, W = sheet.shape[:2]
    assert W > 4 * 64 and H > 48 + 20  # room for the label and time bands
    spots = []
    for tile in tiles:
        found = None
        for y in range(H - 48 + 1):
            for x in range(W - 64 + 1):
                if abs(int(sheet[y + 24, x + 32, 0]) - int(tile[24, 32, 0])) > 1:
                    continue
                if np.abs(sheet[y:y + 48, x:x + 64] - tile).max() <= 1:
                    found = (y, x)
                    break
            if found:
                break
        assert found is not None, "a technique's image is not on the sheet"
        spots.append(found)
    ys, xs = zip(*spots)
    assert len(set(ys)) == 1 and list(xs) == sorted(xs) and len(set(xs)) == 4  # side by side, in order
    # a label above and a time below each image: bright text pixels in both bands
    y = ys[0]
    for x in xs:
        above, below = sheet[:y, x:x + 64], sheet[y + 48:, x:x + 64]
        assert (above.max(axis=2) > 150).sum() > 10 and (below.max(axis=2) > 150).sum() > 10

def test_compare_refuses_unknown_techniques(tmp_path):
    """An unknown name: exit 2, one line naming it and the available ones, nothing written."""
    (tmp_path / "sphere.toml").write_text(SPHERE_TOML)
    res = run_cli(["compare", "sphere.toml", "--techniques", "tsd,nope", "--size", "64x64", "--out", "sheet.png",
                   "--json", "t.json"], tmp_path)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "nope" in lines[0] and "ssss" in lines[0] and "preintegrated" in lines[0], res.stderr
    assert lines[0].startswith("dermis: error:")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sphere.toml"]


def test_techniques_share_specular_and_are_selected_by_name(tmp_path, gl_ctx):
    """The skin techniques draw the same specular (one shared GLSL function): their
    specular-only images agree to 1e-5; and each is chosen by name in a scene file, the API and
    the CLI."""
    import dermis
    from dermis.renderer import Renderer

    (tmp_path / "sphere.toml").write_text(SPHERE_TOML.replace("[scene]\n", '[scene]\ntechnique = "ssss"\n'))
    sc = dermis.load_scene(tmp_path / "sphere.toml")
    assert sc.technique == "ssss"
    with Renderer(sc, (64, 64), ctx=gl_ctx, samples=0, irradiance_size=128) as r:
        r.render()
        assert r.stats["technique"] == "ssss" and "ssss_blur" in r.stats["passes_run"]
        spec = {n: r.render(n, output_mode=2) for n in ("tsd", "ssss", "preintegrated")}
    assert spec["tsd"].max() > 0.01  # there is a highlight
    for n in ("ssss", "preintegrated"):
        assert np.abs(spec[n] - spec["tsd"]).max() < 1e-5, n
    img = dermis.render(sc, technique="preintegrated", size=(32, 32), ctx=gl_ctx, samples=0)
    assert img.shape == (32, 32, 3) and img.max() > 0
    res = run_cli(["render", "sphere.toml", "--technique", "preintegrated", "--size", "32x32", "--out", "p.png",
                   "--stats", "s.json"], tmp_path)
    assert res.returncode == 0, res.stderr
    assert json.loads((tmp_path / "s.json").read_text())["technique"] == "preintegrated"
