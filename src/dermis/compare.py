"""``dermis compare``: the skin techniques side by side on one scene, under identical light.

One Renderer renders every technique at the same size with the same shadows, lights,
environment and output transform; the images are tiled left to right, each labelled with its
technique's name above and its frame time below, and the timings can be written as JSON.

Timing: after a warm-up frame (programs compiled, once-per-mesh work such as tsd's stretch map
done), each timed frame starts from ``Renderer.invalidate()``: shadow maps and every
view-independent pass re-run, as they would with moving lights, so no technique is timed on
another's cached results. The median of ``frames`` frames is reported (``dermis bench`` measures
the camera-moving case too).
"""

from __future__ import annotations

import statistics
from pathlib import Path

import click
import numpy as np

from dermis.errors import DermisError

DEFAULT_TECHNIQUES = "tsd,ssss,preintegrated,lambert"
CREDITS = {  # image credits by mesh file, printed on sheets of those scenes (README, "Credits")
    "leeperrysmith": "Lee Perry-Smith head: Infinite-Realities (www.ir-ltd.net), CC BY 3.0",
}


def parse_techniques(text: str) -> list[str]:
    """Comma-separated technique names, in order, without repeats; unknown names are an error."""
    from dermis.techniques import technique_class

    names = []
    for part in (text or "").split(","):
        name = part.strip()
        if name and name not in names:
            names.append(name)
    if not names:
        raise DermisError("techniques: give at least one technique name")
    for name in names:
        technique_class(name)  # DermisError: unknown technique 'x' (available: ...)
    return names


def render_comparison(scene, techniques, size, *, samples: int = 4, irradiance_size: int = 1024, frames: int = 1,
                      device=None, progress=None):
    """Render each technique once warm, then ``frames`` timed frames from invalidated caches.

    Returns (gl info, {name: linear float32 (H, W, 3)}, {name: timings}) where timings hold
    frame_ms (median), frames_ms, passes_ms (median per pass) and passes_run.
    """
    from dermis.renderer import Renderer

    frames = max(int(frames), 1)
    images, results = {}, {}
    with Renderer(scene, size, device=device, samples=samples, irradiance_size=irradiance_size) as r:
        info = dict(r.info)
        for name in techniques:
            r.render(name)  # warm-up
            times, passes = [], {}
            for _ in range(frames):
                r.invalidate()
                img = r.render(name)
                times.append(float(r.stats["frame_ms"]))
                for k, v in r.stats["passes_ms"].items():
                    passes.setdefault(k, []).append(float(v))
                if progress:
                    progress()
            if not np.isfinite(img).all():
                raise DermisError(f"{scene.source}: technique '{name}' produced NaN or infinite values")
            images[name] = img
            results[name] = {"frame_ms": statistics.median(times), "frames_ms": times,
                             "passes_ms": {k: statistics.median(v) for k, v in passes.items()},
                             "passes_run": list(r.stats["passes_run"])}
    return info, images, results


def format_ms(ms: float) -> str:
    return f"{ms:.1f} ms" if ms < 10 else f"{ms:.0f} ms"


def contact_sheet(tiles, footer_lines=()) -> np.ndarray:
    """Tile (label, display-encoded (H, W, 3) image in [0, 1], caption) left to right on a dark
    sheet, the label above each image and the caption below, optional footer lines at the bottom.
    Returns uint8 (H', W', 3)."""
    from PIL import Image, ImageDraw, ImageFont

    h, w = tiles[0][1].shape[:2]
    font_px = int(np.clip(w / 16, 11, 28))
    try:
        font = ImageFont.load_default(size=font_px)
        small = ImageFont.load_default(size=max(10, int(font_px * 0.6)))
    except TypeError:  # Pillow < 10.1: the bitmap default font has one size
        font = small = ImageFont.load_default()
    pad = max(4, font_px // 3)
    band = font_px + 2 * pad
    foot = (max(10, int(font_px * 0.6)) + pad) * len(footer_lines) + (pad if footer_lines else 0)
    sheet = Image.new("RGB", (len(tiles) * w + (len(tiles) + 1) * pad, h + 2 * band + foot), (16, 16, 18))
    draw = ImageDraw.Draw(sheet)
    for i, (label, img, caption) in enumerate(tiles):
        x = pad + i * (w + pad)
        tile = np.clip(np.asarray(img, np.float32) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        sheet.paste(Image.fromarray(tile), (x, band))
        for text, y, colour in ((label, pad, (235, 235, 235)), (caption, band + h + pad, (200, 200, 160))):
            tw = draw.textlength(text, font=font)
            draw.text((x + (w - tw) / 2, y), text, font=font, fill=colour)
    y = h + 2 * band
    for line in footer_lines:
        draw.text((pad, y), line, font=small, fill=(150, 150, 150))
        y += max(10, int(font_px * 0.6)) + pad
    return np.asarray(sheet)


def _credit(scene) -> str | None:
    src = str(getattr(scene.mesh, "source", "")).lower().replace("-", "").replace("_", "")
    for key, line in CREDITS.items():
        if key in src:
            return line
    return None


@click.command("compare")
@click.argument("scene", required=False)
@click.option("--techniques", default=DEFAULT_TECHNIQUES, show_default=True, help="Comma-separated technique names.")
@click.option("--size", default="512x512", show_default=True, help="Size of each image, WxH.")
@click.option("--out", "-o", default="out/compare.png", show_default=True, help="The sheet (PNG).")
@click.option("--json", "json_out", default=None, help="Write the timings as JSON.")
@click.option("--frames", type=int, default=1, show_default=True, help="Timed frames per technique (median).")
@click.option("--samples", type=int, default=4, show_default=True, help="MSAA samples (capped at 4 on llvmpipe).")
@click.option("--irradiance-size", type=int, default=1024, show_default=True, help="Texture-space resolution (tsd).")
@click.option("--exposure", type=float, default=None, help="Exposure in stops (overrides the scene).")
@click.option("--tonemap", type=click.Choice(["aces", "linear"]), default=None, help="Tone map (overrides the scene).")
@click.option("--device", type=int, default=None, help="EGL device (GPU) index.")
def compare_cmd(scene, techniques, size, out, json_out, frames, samples, irradiance_size, exposure, tonemap, device):
    """Render SCENE (default: the built-in head) with several techniques side by side, with frame times."""
    from dermis.cli import parse_size, scene_from_arg, write_json_atomic
    from dermis.images import write_png
    from dermis.output import output_transform

    names = parse_techniques(techniques)
    w, h = parse_size(size)
    if not 64 <= irradiance_size <= 8192:
        raise DermisError(f"irradiance_size: must be in [64, 8192], got {irradiance_size}")
    if not 1 <= frames <= 1000:
        raise DermisError(f"frames: must be in [1, 1000], got {frames}")
    for p in (Path(x) for x in (out, json_out) if x):
        if not p.parent.exists():
            if p.parent == Path("out"):
                p.parent.mkdir(parents=True, exist_ok=True)
            else:
                raise DermisError(f"{p}: output folder {p.parent} does not exist")
    sc = scene_from_arg(scene)
    info, images, results = render_comparison(sc, names, (w, h), samples=samples, irradiance_size=irradiance_size,
                                              frames=frames, device=device)
    o = sc.output
    ev = exposure if exposure is not None else o.exposure
    tm = tonemap or o.tonemap
    tiles = [(name, output_transform(images[name], ev, tm), format_ms(results[name]["frame_ms"])) for name in names]
    footer = [f"{sc.name}, {w}x{h}, {info['renderer']}; frame time: median of {frames} full frame(s)"]
    credit = _credit(sc)
    if credit:
        footer.append(credit)
    write_png(out, contact_sheet(tiles, footer).astype(np.float32) / 255.0)
    if json_out:
        base = results.get("lambert", {}).get("frame_ms")
        write_json_atomic(json_out, {
            "scene": str(sc.source), "size": [w, h], "samples": samples, "irradiance_size": irradiance_size,
            "frames": frames, "renderer": info, "techniques": results,
            "ratio_to_lambert": {n: results[n]["frame_ms"] / base for n in names} if base else None})
    timings = ", ".join(f"{n} {format_ms(results[n]['frame_ms'])}" for n in names)
    click.echo(f"wrote {out} ({w}x{h}: {timings})")
