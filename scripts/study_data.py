"""Reading ehlsim run output for the scripts in this directory (plot_study.py,
compare_spike_grids.py): one CSV reader and one rule for the steps that did not converge."""
import csv

import numpy as np

# A step whose final residual exceeds this many times solver.tolerance did not converge in any
# attempt; from the first such step on, a run is cut off (its fields can be meaningless).
DIVERGED_RESIDUAL_FACTOR = 100.0


def read_csv(path):
    """Columns of a CSV file with a header, as float arrays (nan allowed)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], rows[1:]
    return {name: np.array([float(r[k]) for r in data]) for k, name in enumerate(header)}


def first_unconverged_step(run, ts):
    """(T of the first step that did not converge, or None; the residual limit used), for a
    run's run.json and timeseries.csv columns: residual far above the tolerance, or
    non-finite values."""
    limit = DIVERGED_RESIDUAL_FACTOR * run["parameters"]["solver"]["tolerance"]
    bad = ~np.isfinite(ts["residual"]) | (ts["residual"] > limit) | ~np.isfinite(ts["Delta"])
    return (float(ts["T"][np.argmax(bad)]) if bad.any() else None), limit
