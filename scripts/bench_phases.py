#!/usr/bin/python3
"""Machine-independent cost of finished ehlsim impact runs, by phase.

    /usr/bin/python3 scripts/bench_phases.py RUN_DIR [RUN_DIR ...]

For each run directory (timeseries.csv, run.json) prints a markdown table with
one row per phase of the impact: steps, multigrid cycles per step, work per
step (deformation evaluations in finest-grid units, the `work` column of
timeseries.csv), retried steps (attempts > 1) and steps kept above
solver.tolerance.  The phases follow the dry Hertz impact of model.md
(contact from T = 1 to 4.218): approach T <= 1, contact 1 < T <= 2.75,
rebound (the spike) 2.75 < T <= 4, collapse of the entrapped pocket T > 4.
"""
import csv
import json
import sys
from pathlib import Path

PHASES = [("approach", 0.0, 1.0), ("contact", 1.0, 2.75), ("rebound", 2.75, 4.0),
          ("collapse", 4.0, float("inf"))]


def phase_rows(run_dir):
    run = json.loads((run_dir / "run.json").read_text())
    tolerance = run["parameters"]["solver"]["tolerance"]
    with open(run_dir / "timeseries.csv", newline="") as f:
        steps = list(csv.DictReader(f))
    rows = []
    for name, lo, hi in PHASES + [("whole run", 0.0, float("inf"))]:
        part = [s for s in steps if lo < float(s["T"]) <= hi]
        if not part:
            continue
        n = len(part)
        rows.append((name, n,
                     sum(int(s["cycles"]) for s in part) / n,
                     sum(float(s["work"]) for s in part) / n,
                     sum(1 for s in part if int(s["attempts"]) > 1),
                     sum(1 for s in part if float(s["residual"]) >= tolerance)))
    return run, rows


def main(dirs):
    for d in dirs:
        run, rows = phase_rows(Path(d))
        r = run["results"]
        print(f"\n{d}: grid {run['grid']['points']}^2, outcome {r.get('outcome')}, "
              f"lift-off {r.get('T_lift_off')}, rebound speed {r.get('rebound_speed')}, "
              f"wall {run.get('wall_seconds', float('nan')):.1f} s\n")
        print("| phase | steps | cycles/step | work/step | retried | kept above tolerance |")
        print("|---|---|---|---|---|---|")
        for name, n, cycles, work, retried, kept in rows:
            print(f"| {name} | {n} | {cycles:.2f} | {work:.1f} | {retried} | {kept} |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
