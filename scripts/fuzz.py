"""``make fuzz``: run the fuzz families of tests/test_fuzz.py for >= 10,000 cases in all, count
OK / clean error / other per family, and write them with the seed to benchmarks/RESULTS.md under
"Reliability". Usage: python scripts/fuzz.py [--cases 10000] [--seed N] [--no-write] [--warnings-as-errors]

Each "other" is printed with its input (the first few per family) and makes the exit status 1.
"""

from __future__ import annotations

import argparse
import collections
import random
import re
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))

# cases per family, as fractions of the total (the cheap families get more)
SHARE = {"toml": 0.2, "gltf": 0.22, "obj": 0.18, "image": 0.15, "api": 0.15, "cli": 0.10}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--families", default=",".join(SHARE))
    ap.add_argument("--warnings-as-errors", action="store_true",
                    help="numpy's RuntimeWarnings (overflow, invalid value) count as 'other': arithmetic on an "
                         "unchecked or overflowing input, even where a clean error follows (round 17)")
    args = ap.parse_args()
    if args.warnings_as_errors:
        import warnings

        warnings.simplefilter("error", RuntimeWarning)
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2**32)

    import test_fuzz as tf

    counts = collections.defaultdict(collections.Counter)
    others = collections.defaultdict(list)

    def record(family, outcome, case):
        counts[family][outcome.kind] += 1
        if outcome.kind == "other" and len(others[family]) < 5:
            others[family].append((outcome.detail, repr(case)[:1500]))
            print(f"OTHER [{family}] {outcome.detail}\n    input: {repr(case)[:1500]}", flush=True)

    tf.RECORD, tf.STRICT = record, False
    families = args.families.split(",")
    total_share = sum(SHARE[f] for f in families)
    t0 = time.time()
    for fam in families:
        n = max(1, round(args.cases * SHARE[fam] / total_share))
        t = time.time()
        # hypothesis may stop a family early when it runs out of distinct cases; top it up
        runs = 0
        while sum(counts[fam].values()) < n and runs < 20:
            tf.family_test(fam, n - sum(counts[fam].values()), seed=seed + runs)()
            runs += 1
        print(f"{fam}: {dict(counts[fam])} in {time.time() - t:.0f} s", flush=True)
    elapsed = time.time() - t0
    total = collections.Counter()
    for c in counts.values():
        total.update(c)
    n_all = sum(total.values())
    print(f"all: {n_all} cases, {dict(total)}, seed {seed}, {elapsed:.0f} s")
    if not args.no_write:
        write_results(counts, total, n_all, seed, elapsed, others)
    return 1 if total["other"] else 0


def write_results(counts, total, n_all, seed, elapsed, others):
    import platform

    lines = ["## Reliability", "",
             f"`make fuzz` (scripts/fuzz.py, hypothesis; tests/fuzzing.py): {n_all} generated inputs, seed {seed}, "
             f"{elapsed / 60:.1f} min on {platform.machine()} ({sys.platform}), frames 16x16 on Mesa llvmpipe. "
             "Strict classification: OK = a finite image (CLI: exit 0, outputs written); clean error = DermisError "
             "with a one-line message (CLI: exit 2, exactly one stderr line, no output or temporary file); "
             "other = anything else.", "",
             "| family | cases | OK | clean error | other |", "| --- | ---: | ---: | ---: | ---: |"]
    for fam, c in counts.items():
        lines.append(f"| {fam} | {sum(c.values())} | {c['ok']} | {c['clean error']} | {c['other']} |")
    lines.append(f"| **all** | **{n_all}** | **{total['ok']}** | **{total['clean error']}** | **{total['other']}** |")
    for fam, items in others.items():
        for detail, case in items:
            lines.append(f"\n- other in {fam}: {detail} (input `{case[:300]}`)")
    section = "\n".join(lines) + "\n"
    path = REPO / "benchmarks" / "RESULTS.md"
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    if "## Reliability" in text:
        text = re.sub(r"## Reliability\n.*?(?=\n## |\Z)", section.rstrip("\n") + "\n", text, flags=re.S)
    else:
        text = text.rstrip("\n") + "\n\n" + section
    path.write_text(text)
    print(f"wrote {path}")


if __name__ == "__main__":
    sys.exit(main())
