#!/usr/bin/python3
"""Grid-refinement check of the spike position: R_s(T) of runs of the same case on different
grids (their spike.csv), interpolated linearly in T to common times, printed as a markdown table
with the differences between successive grids and, for three grids, the observed order.

    /usr/bin/python3 scripts/compare_spike_grids.py RUN_129 RUN_257 RUN_513 [--times 3.0 3.5 ...]

Each RUN is a run directory of `ehlsim impact` (or a case directory of `ehlsim study`), coarse
to fine.  Steps that did not converge (final residual above 100 x solver.tolerance, see
scripts/study_data.py) and everything after them are left out.
"""
import argparse
import json
import math
import os

import numpy as np

from study_data import first_unconverged_step, read_csv

DEFAULT_TIMES = [2.8, 3.0, 3.25, 3.5, 3.75, 3.9, 4.0, 4.05]


def load(run_dir):
    run = json.load(open(os.path.join(run_dir, "run.json")))
    ts = read_csv(os.path.join(run_dir, "timeseries.csv"))
    spike = read_csv(os.path.join(run_dir, "spike.csv"))
    T_unconverged, _ = first_unconverged_step(run, ts)
    T_end = T_unconverged if T_unconverged is not None else np.inf
    keep = spike["T"] < T_end - 1e-9
    return {"n": run["grid"]["points"], "h": run["grid"]["h"], "T": spike["T"][keep],
            "R_s": spike["R_s"][keep], "T_lift_off": run["results"]["T_lift_off"]}


def at(run, t):
    """R_s at time t, linear in T between the two steps around it (nan outside or no spike)."""
    T, R = run["T"], run["R_s"]
    k = np.searchsorted(T, t)
    if k == 0 or k >= len(T):
        return math.nan
    w = (t - T[k - 1]) / (T[k] - T[k - 1])
    return float((1 - w) * R[k - 1] + w * R[k])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("runs", nargs="+")
    parser.add_argument("--times", nargs="+", type=float, default=DEFAULT_TIMES)
    args = parser.parse_args()
    runs = [load(d) for d in args.runs]
    names = [f"{r['n']}^2" for r in runs]
    header = ["T"] + [f"R_s {n}" for n in names] + \
             [f"{names[i + 1]} - {names[i]}" for i in range(len(runs) - 1)]
    if len(runs) == 3:
        header.append("observed order")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for t in args.times:
        values = [at(r, t) for r in runs]
        diffs = [values[i + 1] - values[i] for i in range(len(values) - 1)]
        cells = [f"{t:g}"] + [f"{v:.4f}" for v in values] + [f"{d:+.4f}" for d in diffs]
        if len(runs) == 3:
            ratio = abs(diffs[0] / diffs[1]) if diffs[1] else math.nan
            cells.append(f"{math.log2(ratio):.2f}" if ratio > 0 and math.isfinite(ratio) else "-")
        print("| " + " | ".join(cells) + " |")
    print()
    print("mesh sizes: " + ", ".join(f"{n}: h = {r['h']:.5f}" for n, r in zip(names, runs)))
    print("lift-off: " + ", ".join(f"{n}: {r['T_lift_off']}" for n, r in zip(names, runs)))


if __name__ == "__main__":
    main()
