"""The ``dermis`` command: a thin layer over the Python API.

User errors (DermisError, bad options) print one line, ``dermis: error: ...``, and exit 2; the
library words its errors with the API's argument names (``irradiance_size: ...``), which the CLI
maps to its flags (FLAG_FOR_OPTION). Warnings and log messages of the libraries underneath are
silenced so that the error is the only line. Outputs are all-or-nothing (dermis.fileio.OutputSet).
"""

from __future__ import annotations

import json
import logging
import sys
import warnings
from pathlib import Path

import click

from dermis.errors import DermisError


# API argument names -> the flags that set them (messages "name: ..." become "--flag: ...")
FLAG_FOR_OPTION = {"size": "--size", "technique": "--technique", "irradiance_size": "--irradiance-size",
                   "shadow_size": "--shadow-size", "samples": "--samples", "exposure": "--exposure",
                   "tonemap": "--tonemap", "device": "--device", "techniques": "--techniques", "frames": "--frames",
                   "fps": "--fps", "degrees": "--degrees", "spp": "--spp", "min_spacing_mm": "--spacing", "out": "--out",
                   "workers": "--workers", "ray": "--ray"}


def cli_message(message: str) -> str:
    """A library message in the CLI's words: a leading API argument name becomes its flag."""
    name, sep, rest = message.partition(":")
    if sep and name in FLAG_FOR_OPTION:
        message = FLAG_FOR_OPTION[name] + sep + rest
    # "use a smaller shadow_size" and the like, inside the message
    for name, flag in FLAG_FOR_OPTION.items():
        if "_" in name:
            message = message.replace(name, flag)
    return message


def parse_size(value: str, option="--size") -> tuple[int, int]:
    from dermis.validation import check_size

    try:
        w, h = value.lower().split("x")
        size = (int(w), int(h))
    except Exception:
        raise DermisError(f"{option}: expected WxH such as 512x512, got '{value}'") from None
    return check_size(size, option)


def parse_texture_size(value, option: str) -> int | None:
    """A texture size option: an integer, or "auto" (None: chosen from the mesh's size on screen,
    dermis.adaptive_resolution). The range is checked by the Renderer's own check."""
    if value is None or isinstance(value, int):
        return value
    if str(value).strip().lower() == "auto":
        return None
    try:
        return int(value)
    except ValueError:
        raise DermisError(f"{option}: expected an integer or 'auto', got '{value}'") from None


def scene_from_arg(scene_arg: str | None, technique: str | None = None):
    import dermis

    scene = dermis.default_scene() if scene_arg is None else dermis.load_scene(scene_arg)
    if technique:
        scene.technique = technique
    return scene


def write_json_atomic(path, obj):
    from dermis.images import atomic_write

    text = json.dumps(obj, indent=2, default=float)
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="dermis")
def cli():
    """dermis: physically based real-time skin rendering (texture-space diffusion and friends)."""


@cli.command()
@click.option("--device", type=int, default=None, help="EGL device (GPU) index.")
@click.option("--json", "as_json", is_flag=True, help="Print as JSON.")
def info(device, as_json):
    """Print the OpenGL renderer, version and limits."""
    from dermis.gl.context import create_context, gl_info
    from dermis.techniques import technique_names

    ctx = create_context(device)
    data = gl_info(ctx)
    data["techniques"] = technique_names()
    ctx.release()
    if as_json:
        click.echo(json.dumps(data, indent=2))
    else:
        for k, v in data.items():
            click.echo(f"{k:18s} {v}")


@cli.command()
@click.argument("scene", required=False)
@click.option("--technique", "-t", default=None, help="Technique name (default: the scene's, else tsd).")
@click.option("--size", default="512x512", show_default=True, help="Output size WxH.")
@click.option("--out", "-o", default="out/render.png", show_default=True, help="PNG output (display-encoded).")
@click.option("--exr", default=None, help="Also write the linear HDR image as OpenEXR.")
@click.option("--stats", default=None, help="Write pass timings and frame info as JSON.")
@click.option("--exposure", type=float, default=None, help="Exposure in stops (overrides the scene).")
@click.option("--tonemap", type=click.Choice(["aces", "linear"]), default=None, help="Tone map (overrides the scene).")
@click.option("--samples", type=int, default=4, show_default=True, help="MSAA samples (capped at 4 on llvmpipe).")
@click.option("--irradiance-size", default="auto", show_default=True,
              help="Texture-space resolution (texels), or 'auto': chosen from the head's size on screen "
                   "(d'Eon & Luebke 2007's adaptive resolution, dermis.adaptive_resolution; a close-up "
                   "gets more texels).")
@click.option("--shadow-size", default="auto", show_default=True,
              help="Shadow-map tile per light (texels), or 'auto' (as --irradiance-size).")
@click.option("--debug-buffers", default=None, help="Folder to write intermediate buffers (EXR) into.")
@click.option("--device", type=int, default=None, help="EGL device (GPU) index.")
def render(scene, technique, size, out, exr, stats, exposure, tonemap, samples, irradiance_size, shadow_size, debug_buffers,
           device):
    """Render SCENE (a .toml scene or a .glb/.gltf/.obj mesh; default: the built-in head)."""
    from dermis.fileio import OutputSet
    from dermis.images import exr_writer, png_writer
    from dermis.output import output_transform
    from dermis.renderer import Renderer
    from dermis.techniques import technique_class
    from dermis.validation import check_exposure, check_renderer_options

    w, h = parse_size(size)
    irradiance_size = parse_texture_size(irradiance_size, "--irradiance-size")
    shadow_size = parse_texture_size(shadow_size, "--shadow-size")
    check_renderer_options((w, h), samples, 2048 if shadow_size is None else shadow_size,
                           1024 if irradiance_size is None else irradiance_size, device)
    if exposure is not None:
        check_exposure(exposure)
    named = [("--out", out), ("--exr", exr), ("--stats", stats)]
    for opt, p in named + [("--debug-buffers", debug_buffers)]:
        if p is not None and str(p).strip() == "":
            raise DermisError(f"{opt}: the path is empty")
    files = [(opt, Path(p)) for opt, p in named if p is not None]
    for i, (opt, p) in enumerate(files):
        for opt2, p2 in files[:i]:
            if p.resolve() == p2.resolve():
                raise DermisError(f"{opt}: {p} is the same file as {opt2}")
    if debug_buffers and any(Path(debug_buffers).resolve() == p.resolve() for _, p in files):
        raise DermisError(f"--debug-buffers: {debug_buffers} is also the name of a file output")
    sc = scene_from_arg(scene, technique)
    technique_class(sc.technique)  # unknown names fail before any GL work
    with OutputSet() as outputs:
        for opt, p in files:  # temporaries made now: an unwritable place fails before the render
            if not p.parent.exists() and p.parent == Path("out"):
                p.parent.mkdir(parents=True, exist_ok=True)
            try:
                outputs.reserve(p)
            except DermisError as exc:
                raise DermisError(f"{opt}: {exc}") from None
        dbg = None
        if debug_buffers:
            try:
                dbg = outputs.folder(debug_buffers)
            except DermisError as exc:
                raise DermisError(f"--debug-buffers: {exc}") from None
        with Renderer(sc, (w, h), device=device, samples=samples, irradiance_size=irradiance_size,
                      shadow_size=shadow_size) as r:
            img = r.render()
            o = sc.output
            display = output_transform(img, exposure if exposure is not None else o.exposure, tonemap or o.tonemap,
                                       o.bloom, o.bloom_radius)
            outputs.add(out, png_writer(display))
            if exr:
                outputs.add(exr, exr_writer(img))
            if stats:
                text = json.dumps(r.stats, indent=2, default=float)
                outputs.add(stats, lambda tmp: Path(tmp).write_text(text))
            if dbg is not None:
                for name, arr in r.debug_buffers().items():
                    rgb = arr[:, :, :3] if arr.shape[2] >= 3 else np.repeat(arr[:, :, :1], 3, axis=2)
                    exr_writer(rgb)(dbg / f"{name}.exr")
            frame_ms = r.stats["frame_ms"]
        outputs.commit()
    click.echo(f"wrote {out} ({w}x{h}, {sc.technique}, {frame_ms:.0f} ms)")


import numpy as np  # noqa: E402  (used by commands above)


def _register_optional():
    """Commands from modules that may not be present in every build of the tree."""
    for mod, attr in (("dermis.profiles.cli", "profile_cmd"), ("dermis.bench", "bench_cmd"),
                      ("dermis.compare", "compare_cmd"), ("dermis.reference.cli", "reference_cmd"),
                      ("dermis.reference.cli", "validate_cmd"), ("dermis.viewer.cli", "view_cmd"),
                      ("dermis.viewer.cli", "turntable_cmd"), ("dermis.batch.cli", "batch_cmd"),
                      ("dermis.blender.cli", "export_cmd"), ("dermis.blender.cli", "cycles_cmd")):
        try:
            m = __import__(mod, fromlist=[attr])
        except ModuleNotFoundError as exc:
            if exc.name and mod.startswith(exc.name):
                continue
            raise
        if hasattr(m, attr):
            cli.add_command(getattr(m, attr))


_register_optional()


def quiet_libraries():
    """The error is the only line: numpy/trimesh/pygltflib log records are dropped (dermis checks
    what they warn about and says it in its own words; warnings are ignored around the command)."""
    root = logging.getLogger()
    if not root.handlers:
        root.addHandler(logging.NullHandler())  # no "last resort" printing of library warnings


def main(argv=None):
    quiet_libraries()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cli.main(args=argv, prog_name="dermis", standalone_mode=False)
    except DermisError as exc:
        click.echo(f"dermis: error: {cli_message(str(exc))}", err=True)
        sys.exit(2)
    except click.exceptions.Abort:
        click.echo("dermis: aborted", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        click.echo(f"dermis: error: {exc.format_message()}", err=True)
        sys.exit(exc.exit_code if exc.exit_code else 2)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except KeyboardInterrupt:
        sys.exit(130)
    except MemoryError:
        click.echo("dermis: error: out of memory (try a smaller --size or --irradiance-size)", err=True)
        sys.exit(2)
    sys.exit(0)


if __name__ == "__main__":
    main()
