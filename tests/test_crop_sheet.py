"""benchmarks/crop_sheet.py's Cycles column: a Cycles image of another size (the validation's
64 x 64) is cut from the same millimetre square as the renders, so its tiles show the same part
of the head. Stand-in for Cycles: the render itself, box-downsampled to 64 x 64."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import dermis
from dermis.blender import bpy_available
from dermis.images import write_exr
from dermis.renderer import Renderer

REPO = Path(__file__).resolve().parent.parent


def _crop_sheet():
    spec = importlib.util.spec_from_file_location("crop_sheet", REPO / "benchmarks" / "crop_sheet.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_cycles_column_of_another_size_shows_the_same_crops(gl_ctx, tmp_path):
    cs = _crop_sheet()
    scene_file = REPO / "examples" / "lee-perry-smith.toml"
    S, tile = 256, 48
    with Renderer(dermis.load_scene(scene_file), (S, S), ctx=gl_ctx, irradiance_size=256) as r:
        img = r.render("lambert").astype(np.float32)
        f = r.last_frame
        cam = (img, f.view, f.proj, np.asarray(f.eye))
    small = img.reshape(64, S // 64, 64, S // 64, 3).mean(axis=(1, 3))
    (tmp_path / scene_file.stem).mkdir()
    write_exr(tmp_path / scene_file.stem / "cycles_spec.exr", small)
    sheet_img, rows = cs.sheet(scene_file, [("lambert", cam)], tmp_path, S, 56.0, tile)
    plain, _ = cs.sheet(scene_file, [("lambert", cam)], None, S, 56.0, tile)
    assert rows and "eye +x" in rows
    assert sheet_img.shape[1] == plain.shape[1] + tile + 4  # one more column
    band, pad, x0 = 18, 4, 70
    ours, cyc = [], []
    for i in range(len(rows)):
        y = band + i * (tile + pad)
        ours.append(sheet_img[y:y + tile, x0:x0 + tile].astype(float))
        cyc.append(sheet_img[y:y + tile, x0 + tile + pad:x0 + 2 * tile + pad].astype(float))
        assert cyc[-1].std() > 1.0  # a tile with content, not the padding
    # each Cycles tile is the same square as its row's render tile: closer to it (mean absolute
    # difference of the display values, the 64 x 64 stand-in's tile blurred) than to any other row's
    d = np.array([[np.abs(o - c).mean() for o in ours] for c in cyc])
    print(f"rows {rows}\nmean |difference| (Cycles tile x render tile)\n{np.round(d, 1)}")
    assert np.all(np.diag(d) < 16.0), np.diag(d)
    for i in range(len(rows)):
        assert d[i, i] < 0.6 * np.delete(d[i], i).min(), d


@pytest.mark.skipif(not bpy_available(), reason="bpy (Blender as a Python module) is not installed: the crops' "
                                                "key is the Cycles stores' key, which names Blender's version")
def test_full_resolution_cycles_crops_land_on_their_rows(gl_ctx, tmp_path):
    """benchmarks/cycles_crops.py's stored windows (stand-in: the render's own pixels in each crop's
    box, from cycles_crops.frame_boxes, which computes the boxes without GL) make a column whose
    tiles ARE the render's tiles; a crop stored under another key (a changed scene) is not used."""
    import sys

    cs = _crop_sheet()
    sys.path.insert(0, str(REPO / "benchmarks"))
    import cycles_crops

    scene_file = REPO / "examples" / "lee-perry-smith.toml"
    S, tile = 256, 48
    sc = dermis.load_scene(scene_file)
    with Renderer(sc, (S, S), ctx=gl_ctx, irradiance_size=256) as r:
        img = r.render("lambert").astype(np.float32)
        f = r.last_frame
        cam = (img, f.view, f.proj, np.asarray(f.eye))
    boxes = cycles_crops.frame_boxes(sc, S)
    assert "nose" in boxes and "eye +x" in boxes

    def store(key):
        for lm, (x0, y0, x1, y1) in boxes.items():
            win = np.concatenate([img[y0:y1, x0:x1, :3], np.ones((y1 - y0, x1 - x0, 1), np.float32)], -1)
            k = key or cycles_crops.crop_key(sc, S, (x0, y0, x1, y1), 4, 2)
            cycles_crops.save_crop(tmp_path, scene_file.stem, lm, win,
                                   {"box": [x0, y0, x1, y1], "spp": 4, "seeds": 2, "key": k})
        return cs.sheet(scene_file, [("lambert", cam)], None, S, cs.CROP_MM, tile, cycles_crops=tmp_path)

    plain, _ = cs.sheet(scene_file, [("lambert", cam)], None, S, cs.CROP_MM, tile)
    stale, _ = store("another scene's key")
    assert stale.shape == plain.shape  # no column
    sheet_img, rows = store(None)
    assert sheet_img.shape[1] == plain.shape[1] + tile + 4
    band, pad, x0 = 18, 4, 70
    for i, name in enumerate(rows):
        y = band + i * (tile + pad)
        ours = sheet_img[y:y + tile, x0:x0 + tile].astype(float)
        cyc = sheet_img[y:y + tile, x0 + tile + pad:x0 + 2 * tile + pad].astype(float)
        assert ours.std() > 5.0
        # 7-bit mantissa storage (0.4 %): a grey level at most here and there
        assert np.abs(ours - cyc).mean() < 1.0, name


def _look_zoom():
    import sys

    sys.path.insert(0, str(REPO / "benchmarks"))
    spec = importlib.util.spec_from_file_location("look_zoom", REPO / "benchmarks" / "look_zoom.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_look_zoom_shows_the_pixels_and_ranks_a_planted_comb_first(tmp_path, capsys):
    """benchmarks/look_zoom.py (round 18's review): a zoom tile is the frame's own display pixels
    repeated (nearest), not resampled, at the box's place; `hotspots` puts a comb of stripes that
    one technique has and the others lack in its own window, first. Synthetic frames (no GL)."""
    from PIL import Image

    lz = _look_zoom()
    scene = str(REPO / "examples" / "reference" / "front-key.toml")
    sc = lz.scene_of(scene)
    H = W = 64
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    base = np.stack([0.02 + 0.004 * xx, 0.01 + 0.003 * yy, 0.01 + 0.001 * (xx + yy)], -1)  # a smooth ramp
    imgs = {t: base * (1.0 + 0.02 * i) for i, t in enumerate(lz.TECHNIQUES)}
    imgs["tsd"] = imgs["tsd"].copy()
    imgs["tsd"][16:32, 32:48:2] *= 1.6  # the comb: every other column of one window, in tsd only
    npz = tmp_path / "frames.npz"
    np.savez(npz, **{f"img_{t}": v for t, v in imgs.items()})
    out = tmp_path / "zoom.png"
    box, k = (8, 40, 24, 56), 3
    lz.main(["zoom", str(npz), scene, str(out), "--box", *map(str, box), "--scale", str(k), "--no-cycles"])
    sheet = np.asarray(Image.open(out).convert("RGB"))
    pad, band, side = 4, 16, (box[2] - box[0]) * k
    for j, t in enumerate(lz.TECHNIQUES):
        x, y = pad + j * (side + pad), pad + band
        want = lz.u8(lz.disp(sc, imgs[t][box[1]:box[3], box[0]:box[2]]))
        np.testing.assert_array_equal(sheet[y:y + side, x:x + side], np.repeat(np.repeat(want, k, 0), k, 1))
    capsys.readouterr()
    lz.main(["hotspots", str(npz), scene, "--top", "3", "--win", "16"])
    first = capsys.readouterr().out.splitlines()[0].split()
    print(first)
    assert first[1] == "tsd" and " ".join(first[3:7]) == "(32, 16, 48, 32)", first
