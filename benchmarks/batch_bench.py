"""Batch throughput: the same renders (the first N draws of benchmarks/batch-sweep.toml) through
1 and 2 local workers and a local Ray with 2 actors. Prints a Markdown table for RESULTS.md.

    PYTHONPATH=src python benchmarks/batch_bench.py --renders 200 --work /tmp/batch-bench
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import time
from pathlib import Path

SWEEP = Path(__file__).resolve().parent / "batch-sweep.toml"


def load() -> str:
    return "load average %.2f %.2f %.2f" % os.getloadavg()


def main():
    from dermis.batch import run_batch
    from dermis.batch.dataset import read_table

    ap = argparse.ArgumentParser()
    ap.add_argument("--renders", type=int, default=200)
    ap.add_argument("--work", default="/tmp/dermis-batch-bench")
    ap.add_argument("--configs", default="local1,local2,ray2")
    args = ap.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    runs = {"local1": dict(workers=1), "local2": dict(workers=2), "ray2": dict(workers=2, ray="auto")}
    results = []
    for name in args.configs.split(","):
        out = work / name
        shutil.rmtree(out, ignore_errors=True)
        before = load()
        t0 = time.perf_counter()
        r = run_batch(SWEEP, out, limit=args.renders, progress=False, **runs[name])
        wall = time.perf_counter() - t0
        rows = [x for x in read_table(out).to_pylist() if x["status"] == "ok"]
        med = statistics.median(x["render_ms"] for x in rows)
        tot = statistics.median(x["total_ms"] for x in rows)
        cpu = statistics.median(x["cpu_ms"] for x in rows) if rows and rows[0].get("cpu_ms") is not None else float("nan")
        results.append({"config": name, **r.as_dict(), "wall_s": wall, "median_render_ms": med, "median_total_ms": tot, "median_cpu_ms": cpu,
                        "load_before": before, "load_after": load(), "checksums": {x["render_id"]: x["png_sha256"] for x in rows}})
        print(json.dumps({k: v for k, v in results[-1].items() if k != "checksums"}, default=str), flush=True)
    same = all(x["checksums"] == results[0]["checksums"] for x in results)
    print(f"\nsame images in every configuration: {same}\n")
    print("| executor | renders | start-up (s) | to first image (s) | renders/min (all) | renders/min (warm) | median frame (ms) | median per render (ms) | median CPU per render (ms) | load before -> after |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for x in results:
        print(f"| {x['config']} | {x['ok']} ok, {x['failed']} failed | {x['startup'].get('startup_s', 0):.1f} | "
              f"{x['first_result_s']:.1f} | {x['renders_per_minute']:.1f} | {x['steady_renders_per_minute']:.1f} | "
              f"{x['median_render_ms']:.0f} | {x['median_total_ms']:.0f} | {x['median_cpu_ms']:.0f} | {x['load_before'][13:]} -> {x['load_after'][13:]} |")
    (work / "results.json").write_text(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
