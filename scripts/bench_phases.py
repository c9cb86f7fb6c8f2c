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

Where the run wrote convergence.csv (every cycle of every attempt), a second
table says how the first attempts of the steps fared: the share that reached
the tolerance, their cycles, and their rate (the geometric mean of the
residual ratio per cycle after the first cycle), beside all cycles per step,
failed attempts included.
"""
import csv
import json
import math
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


def first_attempts(run_dir, steps_T, tolerance):
    """Per phase: steps, share of first attempts converged, their cycles and rate, all cycles."""
    first = {}   # step -> residuals of its first attempt (cycle 0 first)
    cycles = {}  # step -> cycles of all its attempts
    attempts = {}
    with open(run_dir / "convergence.csv", newline="") as f:
        for row in csv.DictReader(f):
            step, cycle = int(row["step"]), int(row["cycle"])
            if cycle == 0:
                attempts[step] = attempts.get(step, 0) + 1
            else:
                cycles[step] = cycles.get(step, 0) + 1
            if attempts[step] == 1:
                first.setdefault(step, []).append(float(row["residual"]))
    rows = []
    for name, lo, hi in PHASES:
        part = [s for s in attempts if lo < steps_T.get(s, float("nan")) <= hi]
        if not part:
            continue
        firsts = [first[s] for s in part]
        converged = [r for r in firsts if len(r) > 1 and r[-1] < tolerance]
        ratios = [r[k] / r[k - 1] for r in converged for k in range(2, len(r))
                  if r[k] > 0 and r[k - 1] > 0]
        rate = math.exp(sum(map(math.log, ratios)) / len(ratios)) if ratios else float("nan")
        their_cycles = (sum(len(r) - 1 for r in converged) / len(converged) if converged
                        else float("nan"))
        every = sum(cycles.get(s, 0) for s in part) / len(part)
        rows.append((name, len(part), len(converged) / len(part), their_cycles, rate, every))
    return rows


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
        run_dir = Path(d)
        if not (run_dir / "convergence.csv").exists():
            continue
        with open(run_dir / "timeseries.csv", newline="") as f:
            steps_T = {k + 1: float(s["T"]) for k, s in enumerate(csv.DictReader(f))}
        first_step = run.get("invocation", {}).get("restart", {}).get("step", 0)
        steps_T = {k + first_step: T for k, T in steps_T.items()}
        tolerance = run["parameters"]["solver"]["tolerance"]
        print("\n| phase | steps | first attempts converged | their cycles | their rate "
              "| all cycles per step |")
        print("|---|---|---|---|---|---|")
        for name, n, share, cycles, rate, every in first_attempts(run_dir, steps_T, tolerance):
            print(f"| {name} | {n} | {100 * share:.0f} % | {cycles:.2f} | {rate:.3f} | {every:.2f} |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
