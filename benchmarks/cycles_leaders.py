"""The rows of a ``dermis validate --against cycles --json`` report where tsd is NOT the closest to Cycles
(issue 12's goal: tsd closest of all techniques, and closer than Cycles' own render without subsurface
scattering, in every scene's mean FLIP and every region): each such row with tsd's FLIP and the best other's,
compared at 4 decimals as the reports print them (a tie counts).

    python benchmarks/cycles_leaders.py benchmarks/cycles/validate-64x64-converged-4scenes-round13.json
"""

from __future__ import annotations

import json
import sys

REGIONS = ("ALL", "back_lit_ear", "eyelids", "nose_shadow_penumbra", "shadow_edge", "backlit_thin", "lips")


def rows_not_led(report: dict):
    """[(scene/mode, region, tsd's FLIP, best other technique, its FLIP)] and the number of rows."""
    out, total = [], 0
    for scene, d in report["scenes"].items():
        for reg in REGIONS:
            vals = {}
            for t, td in d["techniques"].items():
                v = td["flip"] if reg == "ALL" else td.get("regions", {}).get(reg, {}).get("flip")
                if v is not None:
                    vals[t] = v
            if "tsd" not in vals or len(vals) < 2:
                continue
            total += 1
            best, who = min((v, t) for t, v in vals.items() if t != "tsd")
            if round(best, 4) <= round(vals["tsd"], 4):
                out.append((scene, reg, vals["tsd"], who, best))
    return out, total


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    for path in argv:
        with open(path) as f:
            rows, total = rows_not_led(json.load(f))
        print(f"== {path}")
        for scene, reg, tsd, who, best in rows:
            print(f"{scene:20s} {reg:22s} tsd {tsd:.4f}  best other {who} {best:.4f}  (by {tsd - best:+.4f})")
        print(f"{len(rows)} of {total} rows where another is as close or closer")


if __name__ == "__main__":
    main()
