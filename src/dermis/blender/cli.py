"""``dermis export`` and ``dermis cycles`` (registered by dermis.cli when this module exists).
Without bpy they stop with one line saying how to install the ``cycles`` extra (exit 2)."""

from __future__ import annotations

from pathlib import Path

import click

from dermis.errors import DermisError


@click.command("export")
@click.argument("scene")
@click.argument("out")
@click.option("--size", default="512x512", show_default=True, help="Render size stored in the .blend (WxH).")
@click.option("--sss/--no-sss", default=True, show_default=True, help="Skin as random-walk subsurface (else plain diffuse).")
@click.option("--specular/--no-specular", default=True, show_default=True, help="The skin's specular lobe.")
def export_cmd(scene, out, size, sss, specular):
    """Write SCENE as a Blender scene OUT (.blend): mesh, skin material, camera, lights, world,
    in metres with Blender's z up; open it in Blender and render with Cycles."""
    from dermis.blender import require_bpy
    from dermis.blender.export import ExportOptions, export_blend
    from dermis.blender.sss import cycles_subsurface
    from dermis.cli import parse_size, scene_from_arg

    w, h = parse_size(size)
    if Path(out).suffix.lower() != ".blend":
        raise DermisError(f"{out}: the output must be a .blend file")
    if not Path(out).parent.exists():
        raise DermisError(f"{out}: output folder {Path(out).parent} does not exist")
    require_bpy()
    sc = scene_from_arg(scene)
    export_blend(sc, out, ExportOptions(sss=sss, specular=specular), (w, h))
    msg = f"wrote {out} ({len(sc.lights)} lights, {w}x{h})"
    if sss:
        p = cycles_subsurface(sc)
        msg += (f"; subsurface radius {', '.join(f'{r:.3f}' for r in p.radius_mm)} mm "
                f"(edge-response residual {', '.join(f'{r:.4f}' for r in p.residual)})")
    click.echo(msg)


@click.command("cycles")
@click.argument("scene", required=False)
@click.option("--size", default="128x128", show_default=True, help="Output size WxH.")
@click.option("--out", "-o", default="out/cycles.exr", show_default=True, help=".exr (linear radiance) or .png (display).")
@click.option("--spp", type=int, default=64, show_default=True, help="Cycles samples per pixel.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--sss/--no-sss", default=True, show_default=True)
@click.option("--specular/--no-specular", default=True, show_default=True)
def cycles_cmd(scene, size, out, spp, seed, sss, specular):
    """Render SCENE with Blender Cycles (CPU) through bpy, exactly as `dermis export` sets it up."""
    from dermis.blender import require_bpy
    from dermis.blender.render import render_cycles
    from dermis.cli import parse_size, scene_from_arg
    from dermis.images import write_exr, write_png
    from dermis.output import output_transform

    w, h = parse_size(size)
    if not 1 <= spp <= 1 << 16:
        raise DermisError(f"--spp must be in [1, 65536], got {spp}")
    if Path(out).suffix.lower() not in (".exr", ".png"):
        raise DermisError(f"--out {out}: use a .exr or .png file name")
    if not Path(out).parent.exists():
        raise DermisError(f"{out}: output folder {Path(out).parent} does not exist")
    require_bpy()
    sc = scene_from_arg(scene)
    img, st = render_cycles(sc, (w, h), spp=spp, seed=seed, sss=sss, specular=specular)
    if Path(out).suffix.lower() == ".exr":
        write_exr(out, img)
    else:
        write_png(out, output_transform(img, sc.output.exposure, sc.output.tonemap))
    click.echo(f"wrote {out} ({w}x{h}, {spp} spp, {st['render_s']:.1f} s)")
