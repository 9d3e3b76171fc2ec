"""``dermis view`` and ``dermis turntable`` (registered by dermis.cli when this module exists)."""

from __future__ import annotations

from pathlib import Path

import click

from dermis.errors import DermisError


def _irradiance(n: int) -> int:
    if not 64 <= n <= 8192:
        raise DermisError(f"--irradiance-size must be in [64, 8192], got {n}")
    return n


@click.command("view")
@click.argument("scene", required=False)
@click.option("--technique", "-t", default=None, help="Technique to start with (default: the scene's).")
@click.option("--size", default="960x640", show_default=True, help="Window size WxH (screen pixels).")
@click.option("--irradiance-size", type=int, default=None,
              help="Texture-space resolution (the panel changes it; default: chosen from the head's size on "
                   "screen and re-chosen as the view zooms, dermis.adaptive_resolution).")
@click.option("--shadow-size", type=int, default=None,
              help="Shadow-map tile per light (texels; default: chosen from the head's size on screen and "
                   "re-chosen as the view zooms).")
@click.option("--samples", type=int, default=4, show_default=True, help="MSAA samples (capped at 4 on llvmpipe).")
@click.option("--script", "script_path", default=None, type=click.Path(dir_okay=False),
              help="JSON file of scripted per-frame actions (see dermis.viewer.script).")
@click.option("--no-gui", is_flag=True, help="Start with the panel hidden (Tab shows it).")
@click.option("--screenshot-dir", default=".", show_default=True, help="Folder for screenshots taken with S.")
@click.option("--progressive/--no-progressive", default=True, show_default=True,
              help="Reduced frames while dragging, the full frame when input stops.")
def view_cmd(scene, technique, size, irradiance_size, shadow_size, samples, script_path, no_gui, screenshot_dir, progressive):
    """Open SCENE in an interactive window: orbit, light, skin and output controls, buffer views.

    Left-drag orbits, shift-drag or middle-drag pans, the wheel zooms, right-drag moves the
    selected light; S saves a screenshot, Tab hides the panel, Esc quits. Needs a display
    (on a headless machine: xvfb-run -a dermis view ...).
    """
    from dermis.cli import parse_size, scene_from_arg
    from dermis.techniques import technique_class
    from dermis.viewer.app import check_display, view
    from dermis.viewer.script import Script

    w, h = parse_size(size)
    if irradiance_size is not None:
        _irradiance(irradiance_size)
    if shadow_size is not None:
        from dermis.validation import SHADOW_SIZES

        if not SHADOW_SIZES[0] <= shadow_size <= SHADOW_SIZES[1]:
            raise DermisError(f"--shadow-size must be in [{SHADOW_SIZES[0]}, {SHADOW_SIZES[1]}], got {shadow_size}")
    script = Script.from_file(script_path) if script_path else None
    check_display()  # before loading a scene: the error a headless user sees first
    sc = scene_from_arg(scene, technique)
    technique_class(sc.technique)
    report = view(sc, (w, h), irradiance_size=irradiance_size, shadow_size=shadow_size, samples=samples, script=script, show_gui=not no_gui,
                  screenshot_dir=screenshot_dir, progressive=progressive)
    if script is not None:
        click.echo(f"viewer: {report['frames']} frames, {len(report['screenshots'])} screenshots")


@click.command("turntable")
@click.argument("scene", required=False)
@click.option("--frames", "-n", type=int, default=60, show_default=True, help="Number of frames.")
@click.option("--size", default="512x512", show_default=True, help="Frame size WxH.")
@click.option("--out", "-o", default="out/turntable.mp4", show_default=True,
              help="Output: .mp4 (H.264), .gif, or a folder for PNG frames.")
@click.option("--technique", "-t", default=None, help="Technique (default: the scene's).")
@click.option("--orbit-light", is_flag=True, help="Turn the lights with the camera (a head on a turntable in a "
                                                   "fixed studio); default: lights stay fixed to the head.")
@click.option("--degrees", type=float, default=360.0, show_default=True, help="Total turn over all frames.")
@click.option("--fps", type=float, default=24.0, show_default=True, help="Frames per second of the video.")
@click.option("--exposure", type=float, default=None, help="Exposure in stops (overrides the scene).")
@click.option("--tonemap", type=click.Choice(["aces", "linear"]), default=None, help="Tone map (overrides the scene).")
@click.option("--samples", type=int, default=4, show_default=True, help="MSAA samples.")
@click.option("--irradiance-size", type=int, default=1024, show_default=True, help="Texture-space resolution (tsd).")
@click.option("--device", type=int, default=None, help="EGL device (GPU) index.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def turntable_cmd(scene, frames, size, out, technique, orbit_light, degrees, fps, exposure, tonemap, samples,
                  irradiance_size, device, quiet):
    """Render SCENE turning around its target into a video (.mp4, .gif) or PNG frames."""
    from dermis.cli import parse_size, scene_from_arg
    from dermis.viewer.turntable import output_kind, turntable

    w, h = parse_size(size)
    _irradiance(irradiance_size)
    output_kind(out)
    p = Path(out)
    if not p.parent.exists():
        if p.parent == Path("out"):
            p.parent.mkdir(parents=True, exist_ok=True)
        else:
            raise DermisError(f"{p}: output folder {p.parent} does not exist")
    sc = scene_from_arg(scene, technique)
    res = turntable(sc, p, frames=frames, size=(w, h), technique=technique, orbit_light=orbit_light, degrees=degrees,
                    fps=fps, irradiance_size=irradiance_size, samples=samples, device=device, exposure=exposure,
                    tonemap=tonemap, progress=not quiet)
    ms = sum(res["frame_ms"]) / max(len(res["frame_ms"]), 1)
    click.echo(f"wrote {out} ({res['frames']} frames, {w}x{h}, {res['technique']}, {ms:.0f} ms/frame)")
