"""``dermis batch SWEEP.toml --out DIR``: render a parameter sweep into a dataset."""

from __future__ import annotations

import click


@click.command("batch")
@click.argument("sweep")
@click.option("--out", "-o", required=True, help="Dataset folder (created; a re-run resumes it).")
@click.option("--workers", "-j", type=int, default=None,
              help="Local worker processes (default: CPU cores, at most 4), or Ray actors (default: one per GPU, else per CPU).")
@click.option("--ray", "ray_address", default=None, metavar="auto|ADDRESS",
              help="Run on Ray: 'auto' for a Ray on this machine, or a cluster address (needs dermis[ray]).")
@click.option("--device", type=int, default=None, help="EGL device (GPU) index for local workers.")
@click.option("--limit", type=int, default=None, help="Render at most this many of the renders left.")
@click.option("--dry-run", is_flag=True, help="Print how many renders the sweep has and how many are left; render nothing.")
@click.option("--stats", default=None, help="Write the run's counts and timings as JSON.")
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def batch_cmd(sweep, out, workers, ray_address, device, limit, dry_run, stats, no_progress):
    """Render the sweep SWEEP.toml (docs/batch.md) into the dataset folder --out."""
    from pathlib import Path

    from dermis.errors import DermisError

    if workers is not None and workers < 1:
        raise DermisError(f"--workers: must be >= 1, got {workers}")
    if limit is not None and limit < 0:
        raise DermisError(f"--limit must be >= 0, got {limit}")
    if dry_run:
        from dermis.batch.dataset import JOURNAL, Dataset
        from dermis.batch.sweep import expand, load_sweep

        sw = load_sweep(sweep)
        specs = expand(sw)
        left = len(specs)
        if (Path(out) / JOURNAL).is_file():
            data = Dataset(out, sw)
            left = sum(not data.finished(s) for s in specs)
            data.close()
        click.echo(f"{sweep}: {len(specs)} renders ({sw.mode}), {left} left to render in {out}")
        return
    from dermis.batch.run import run_batch

    result = run_batch(sweep, out, workers=workers, ray=ray_address, device=device, progress=not no_progress, limit=limit)
    if stats:
        from dermis.cli import write_json_atomic

        write_json_atomic(stats, result.as_dict())
    done = result.skipped + result.ok
    if result.interrupted:
        click.echo(f"dermis: interrupted: {out} holds {done} finished renders of {result.total}; "
                   "run the same command again to resume", err=True)
        raise SystemExit(130)
    rate = f", {result.renders_per_minute:.1f} renders/min after {result.startup.get('startup_s', 0):.1f} s start-up" \
        if result.ok + result.failed else ""
    click.echo(f"{out}: {done} of {result.total} renders done ({result.ok} now, {result.skipped} before)"
               f"{f', {result.failed} failed (see the error column of metadata.parquet)' if result.failed else ''}{rate}")
