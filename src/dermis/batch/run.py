"""The batch driver: the render list, what is left of it, an executor, and the dataset.

The driver is the only writer of the dataset: it hands renders out, writes each result's files
and journal row as it arrives (dermis.batch.dataset), and on the way out (done, Ctrl-C, or an
error) stops the workers and writes the Parquet table of what finished.
"""

from __future__ import annotations

import os
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class BatchResult:
    out: Path
    total: int  # renders in the sweep
    skipped: int  # already in the dataset when the run began
    ok: int = 0  # rendered by this run
    failed: int = 0
    interrupted: bool = False
    startup: dict = field(default_factory=dict)
    render_s: float = 0.0  # from the workers being ready to the last result
    first_result_s: float = 0.0  # from the workers being ready to the first result (scene load, shader compile)

    @property
    def renders_per_minute(self) -> float:
        """Over the whole render phase (first renders' scene load and shader compile included)."""
        n = self.ok + self.failed
        return 60.0 * n / self.render_s if self.render_s > 0 else 0.0

    @property
    def steady_renders_per_minute(self) -> float:
        """Between the first result and the last: the rate once the workers are warm."""
        n = self.ok + self.failed
        span = self.render_s - self.first_result_s
        return 60.0 * (n - 1) / span if n > 1 and span > 0 else 0.0

    def as_dict(self) -> dict:
        return {"out": str(self.out), "total": self.total, "skipped": self.skipped, "ok": self.ok, "failed": self.failed,
                "interrupted": self.interrupted, "startup": self.startup, "render_s": self.render_s,
                "first_result_s": self.first_result_s, "renders_per_minute": self.renders_per_minute,
                "steady_renders_per_minute": self.steady_renders_per_minute}


def default_workers() -> int:
    return max(1, min(os.cpu_count() or 1, 4))


def make_executor(sweep, workers=None, ray=None, device=None):
    from dermis.batch.executors import LocalExecutor, RayExecutor
    from dermis.batch.worker import worker_config

    config = worker_config(sweep, device=device)
    if ray:
        return RayExecutor(config, workers, ray)
    return LocalExecutor(config, workers or default_workers())


def run_batch(sweep_path, out, *, workers: int | None = None, ray: str | None = None, device: int | None = None,
              progress: bool = True, limit: int | None = None) -> BatchResult:
    """Render what is left of a sweep into the dataset folder ``out``.

    ``workers``: local processes (default: the CPU cores, at most 4) or Ray actors (default: one
    per GPU, else one per CPU); ``ray``: None (local), "auto" or a Ray address; ``limit``: render
    at most this many (the first ones left). Ctrl-C stops the run with a consistent dataset and
    returns with ``interrupted``; a re-run resumes."""
    from tqdm import tqdm

    from dermis.batch.dataset import Dataset
    from dermis.batch.sweep import expand, load_sweep
    from dermis.errors import DermisError

    sweep = load_sweep(sweep_path)
    specs = expand(sweep)
    if ray is not None:  # the install hint before any file is made
        try:
            import ray as _ray  # noqa: F401
        except ModuleNotFoundError:
            from dermis.batch.executors import INSTALL_RAY

            raise DermisError(INSTALL_RAY) from None
    data = Dataset(out, sweep)
    todo = deque(s for s in specs if not data.finished(s))
    result = BatchResult(Path(out), len(specs), len(specs) - len(todo))
    if limit is not None:
        todo = deque(list(todo)[:limit])
    executor = None
    bar = None
    try:
        data.write_table(specs)
        if not todo:
            return result
        executor = make_executor(sweep, workers, ray, device)
        result.startup = executor.start()
        t0 = time.perf_counter()
        bar = tqdm(total=len(todo), unit="render", desc="dermis batch", file=sys.stderr, disable=not progress,
                   dynamic_ncols=True, smoothing=0.05)
        while todo or executor.busy():
            while todo and executor.has_slot():
                executor.submit(todo.popleft())
            for _spec, row, files in executor.results(timeout=0.5):
                data.commit(row, files)
                if not result.first_result_s:
                    result.first_result_s = time.perf_counter() - t0
                if row["status"] == "ok":
                    result.ok += 1
                else:
                    result.failed += 1
                bar.update(1)
                if result.failed:
                    bar.set_postfix(failed=result.failed, refresh=False)
        result.render_s = time.perf_counter() - t0
    except KeyboardInterrupt:
        result.interrupted = True
    finally:
        if bar is not None:
            bar.close()
        if executor is not None:
            executor.close(abort=result.interrupted or sys.exc_info()[0] is not None)
        data.write_table(specs)
        data.close()
    return result
