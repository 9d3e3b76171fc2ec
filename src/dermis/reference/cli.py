"""``dermis reference`` and ``dermis validate`` (registered by dermis.cli when this module exists)."""

from __future__ import annotations

from pathlib import Path

import click

from dermis.errors import DermisError


def _check_out(path: Path):
    if not path.parent.exists():
        if path.parent == Path("out"):
            path.parent.mkdir(parents=True, exist_ok=True)
        else:
            raise DermisError(f"{path}: output folder {path.parent} does not exist")


@click.command("reference")
@click.argument("scene", required=False)
@click.option("--size", default="256x256", show_default=True, help="Output size WxH.")
@click.option("--out", "-o", default="out/reference.exr", show_default=True,
              help="Output: .exr (linear radiance, as `render --exr`) or .png (display-encoded).")
@click.option("--png", default=None, help="Also write the display-encoded image as PNG.")
@click.option("--spp", type=int, default=4, show_default=True, help="Sub-pixel rays per pixel (4 = the 4x MSAA pattern).")
@click.option("--spacing", type=float, default=None,
              help="Finest surface-sample spacing in mm (default: 0.35 of the pixel footprint, at most 0.25).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the sample lattices.")
@click.option("--paths", type=click.Choice(["straight", "tissue"]), default="straight", show_default=True,
              help="straight: light between any two points by 3-D distance; tissue: not across air gaps (creases).")
@click.option("--stats", default=None, help="Write sample counts and timings as JSON.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def reference_cmd(scene, size, out, png, spp, spacing, seed, paths, stats, quiet):
    """Render SCENE with the offline reference: the same skin model integrated over the surface
    (ray-cast visibility and shadows, 3-D profile integral). Slow: minutes at 512x512."""
    from dermis.cli import parse_size, scene_from_arg, write_json_atomic
    from dermis.images import write_exr, write_png
    from dermis.output import output_transform
    from dermis.reference.render import render_reference

    w, h = parse_size(size)
    if spp < 1 or spp > 64:
        raise DermisError(f"--spp must be in [1, 64], got {spp}")
    if spacing is not None and not 0.005 <= spacing <= 10.0:
        raise DermisError(f"--spacing must be in [0.005, 10] mm, got {spacing}")
    for p in (out, png, stats):
        if p:
            _check_out(Path(p))
    if Path(out).suffix.lower() not in (".exr", ".png"):
        raise DermisError(f"--out {out}: use a .exr or .png file name")
    sc = scene_from_arg(scene)
    if sc.material.pore_strength > 0:
        click.echo("note: the reference has no procedural pore normals (pore_strength ignored); "
                   "compare with pore_strength = 0", err=True)
    res = render_reference(sc, (w, h), spp=spp, min_spacing_mm=spacing, seed=seed, progress=not quiet, paths=paths)
    o = sc.output
    disp = output_transform(res.image, o.exposure, o.tonemap)
    if Path(out).suffix.lower() == ".exr":
        write_exr(out, res.image)
    else:
        write_png(out, disp)
    if png:
        write_png(png, disp)
    if stats:
        write_json_atomic(stats, res.stats)
    st = res.stats
    click.echo(f"wrote {out} ({w}x{h}, {spp} spp, {st.get('samples', 0):,} surface samples at "
               f"{st.get('min_spacing_mm', float('nan')):.3f} mm, {st['visible_points']:,} visible points, {st['total_s']:.1f} s)")


@click.command("validate")
@click.argument("scenes", nargs=-1)
@click.option("--techniques", default="tsd,ssss,preintegrated,lambert", show_default=True,
              help="Comma-separated techniques; unavailable ones are skipped with a note.")
@click.option("--size", default="256x256", show_default=True, help="Image size WxH.")
@click.option("--json", "json_path", default=None, help="Write the report as JSON; error images go beside it.")
@click.option("--images", default=None, help="Folder for the images (default: beside --json, else out/validate).")
@click.option("--spp", type=int, default=4, show_default=True, help="Reference sub-pixel rays per pixel.")
@click.option("--spacing", type=float, default=None, help="Reference finest sample spacing in mm (default: automatic).")
@click.option("--attribution/--no-attribution", default=True, show_default=True,
              help="Re-render tsd with one pipeline part toggled at a time, to say what costs its error.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
@click.option("--against", type=click.Choice(["reference", "cycles"]), default="reference", show_default=True,
              help="reference: dermis's offline reference; cycles: Blender Cycles through bpy (the cycles extra); "
                   "then --spp is Cycles' starting samples, doubled until two seeds differ by FLIP <= 0.01.")
@click.option("--max-spp", type=int, default=1024, show_default=True, help="--against cycles: the most samples per pixel.")
@click.option("--supersample", type=int, default=4, show_default=True,
              help="--against cycles: render each technique at this many times the size and reconstruct it with "
                   "Cycles' pixel filter (1: the technique's own pixels).")
def validate_cmd(scenes, techniques, size, json_path, images, spp, spacing, attribution, quiet, against, max_spp,
                 supersample):
    """Compare techniques with the offline reference on SCENES (default: examples/reference/*.toml):
    mean FLIP, SSIM and relative RMSE on the skin pixels, with FLIP error images."""
    from dermis.cli import parse_size, write_json_atomic
    from dermis.reference.validate import default_scene_files, markdown_table, validate

    w, h = parse_size(size)
    names = [t.strip() for t in techniques.split(",") if t.strip()]
    if not names:
        raise DermisError("--techniques: give at least one technique name")
    files = [Path(s) for s in scenes] if scenes else default_scene_files()
    for f in files:
        if not f.is_file():
            raise DermisError(f"{f}: file not found")
    if json_path:
        _check_out(Path(json_path))
        img_dir = Path(images) if images else Path(json_path).with_suffix("")
    else:
        img_dir = Path(images) if images else Path("out/validate")
    _check_out(img_dir)
    if against == "cycles":  # dermis.blender owns it (bpy)
        from dermis.blender.validate import markdown_table as cycles_table, validate_cycles

        report = validate_cycles(files, names, (w, h), out_dir=img_dir, spp=spp, max_spp=max_spp,
                                 supersample=supersample, echo=click.echo)
        click.echo(cycles_table(report))
        if json_path:
            write_json_atomic(json_path, report)
        return
    report = validate(files, names, (w, h), out_dir=img_dir, spp=spp, spacing_mm=spacing, attribution=attribution,
                      progress=not quiet, echo=click.echo)
    report["images"] = str(img_dir)
    click.echo(markdown_table(report))
    if json_path:
        write_json_atomic(json_path, report)
        click.echo(f"wrote {json_path} (images in {img_dir})")
