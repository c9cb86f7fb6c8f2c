"""Reading and comparing the outputs of ehlsim runs, bit for bit.

An impact's run directory holds timeseries.csv, spike.csv, convergence.csv, fields.nc and
run.json, a rolling contact's profile_x.csv and profile_y.csv instead of the first two
(docs/usage.md, "Outputs").  The comparisons here are exact:

- the CSV files as text (rows of the same steps must be the same strings);
- fields.nc through `ncdump -p 9,17`: 17 significant digits give every double
  back exactly, so equal text means equal bits (header and attributes
  included);
- run.json as parsed JSON (nlohmann writes doubles with round-trip
  precision), without the wall-clock fields;
- checkpoint.nc, when there is one, through ncdump like fields.nc.

Every compare_* function returns a list of differences, one line each
(empty: equal), so that a test can print all of them.
"""
import json
import re
import subprocess
from pathlib import Path

CSV_FILES = ("timeseries.csv", "spike.csv")
# The rolling contact's (one steady solution; no time series).
ROLLING_CSV_FILES = ("profile_x.csv", "profile_y.csv")
# One row per multigrid cycle, the step number first: several rows per step.
CONVERGENCE_FILE = "convergence.csv"
FIELDS_FILE = "fields.nc"
RUN_FILE = "run.json"
CHECKPOINT_FILE = "checkpoint.nc"
# run.json keys that measure the machine, not the computation.
WALL_CLOCK_KEYS = ("wall_seconds", "solver_wall_seconds")
# Digits of ncdump's doubles: enough to give every double back exactly.
NCDUMP_PRECISION = "9,17"
# How many differences of one comparison are listed at most.
MAX_LISTED = 5


def read_rows(path):
    """The header and the data rows of a CSV file, as text."""
    lines = Path(path).read_text().splitlines()
    return lines[0], lines[1:]


def ncdump(path, variables=None):
    """ncdump's text of a NetCDF file at full double precision."""
    command = ["ncdump", "-p", NCDUMP_PRECISION]
    if variables:
        command += ["-v", ",".join(variables)]
    return subprocess.run(command + [str(path)], check=True, capture_output=True,
                          text=True).stdout


def read_snapshots(path):
    """{T text: (P values, H values)} of fields.nc, each value as text."""
    data = ncdump(path, ["time", "P", "H"]).split("data:", 1)[1]
    arrays = {}
    for name, values in re.findall(r"(\w+) =([^;]*);", data):
        arrays[name] = values.replace("\n", " ").split(",")
    arrays = {name: [v.strip() for v in values] for name, values in arrays.items()}
    times = arrays["time"]
    size = len(arrays["P"]) // len(times)
    return {t: (arrays["P"][k * size:(k + 1) * size], arrays["H"][k * size:(k + 1) * size])
            for k, t in enumerate(times)}


def read_run(path):
    """run.json without the wall-clock fields."""
    run = json.loads(Path(path).read_text())
    for key in WALL_CLOCK_KEYS:
        run.pop(key, None)
    return run


def listed(differences, what):
    """The first MAX_LISTED differences and a count of the rest."""
    if len(differences) > MAX_LISTED:
        rest = len(differences) - MAX_LISTED
        differences = differences[:MAX_LISTED] + [f"{what}: ... and {rest} more"]
    return differences


def compare_rows(a_rows, b_rows, what, first_row=0):
    """Row by row; `first_row` numbers the rows in the messages (0: the first data row)."""
    out = []
    if len(a_rows) != len(b_rows):
        out.append(f"{what}: {len(a_rows)} rows against {len(b_rows)}")
    for k, (a, b) in enumerate(zip(a_rows, b_rows)):
        if a != b:
            out.append(f"{what}: data row {first_row + k + 1}: '{a}' != '{b}'")
    return listed(out, what)


def compare_snapshots(a, b, what):
    """Two {T: (P, H)} maps: the same times, and the same values at each."""
    out = []
    if sorted(a) != sorted(b):
        out.append(f"{what}: snapshot times {sorted(a)} != {sorted(b)}")
    for t in sorted(set(a) & set(b)):
        for name, va, vb in zip(("P", "H"), a[t], b[t]):
            diff = [k for k, (x, y) in enumerate(zip(va, vb)) if x != y]
            if diff or len(va) != len(vb):
                out.append(f"{what}: {name} at T = {t}: {len(diff)} values differ "
                           f"(first at index {diff[0] if diff else len(va)})")
    return listed(out, what)


def compare_json(a, b, what):
    """Two JSON values, key by key."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            if key not in a or key not in b:
                out.append(f"{what}.{key}: only in one of the two")
            else:
                out += compare_json(a[key], b[key], f"{what}.{key}")
        return out
    return [] if a == b else [f"{what}: {a!r} != {b!r}"]


def compare_runs(a, b):
    """Two runs of the same input: every output the same (apart from wall-clock time)."""
    a, b = Path(a), Path(b)
    out = []
    rolling = (a / ROLLING_CSV_FILES[0]).exists()
    for name in (ROLLING_CSV_FILES if rolling else CSV_FILES) + (CONVERGENCE_FILE,):
        (header_a, rows_a), (header_b, rows_b) = read_rows(a / name), read_rows(b / name)
        out += compare_rows(rows_a, rows_b, name)
        if header_a != header_b:
            out.append(f"{name}: the headers differ")
    if ncdump(a / FIELDS_FILE) != ncdump(b / FIELDS_FILE):
        differences = compare_snapshots(read_snapshots(a / FIELDS_FILE),
                                        read_snapshots(b / FIELDS_FILE), FIELDS_FILE)
        out += differences or [f"{FIELDS_FILE}: the headers or attributes differ"]
    out += compare_json(read_run(a / RUN_FILE), read_run(b / RUN_FILE), RUN_FILE)
    checkpoints = [run / CHECKPOINT_FILE for run in (a, b)]
    if any(c.exists() for c in checkpoints):
        if not all(c.exists() for c in checkpoints) or ncdump(checkpoints[0]) != ncdump(checkpoints[1]):
            out.append(f"{CHECKPOINT_FILE}: the last checkpoints differ")
    return out


def compare_restart(full, restarted, step):
    """A run restarted after `step` against the uninterrupted run `full`: its
    rows are the full run's rows after `step`, its snapshots the full run's
    snapshots of the same steps, and its results (the whole-run summary) the
    full run's."""
    full, restarted = Path(full), Path(restarted)
    out = []
    for name in CSV_FILES:
        rows = read_rows(full / name)[1]
        out += compare_rows(rows[step:], read_rows(restarted / name)[1], name, step)
    cycles = read_rows(full / CONVERGENCE_FILE)[1]
    after = [row for row in cycles if int(row.split(",")[0]) > step]
    out += compare_rows(after, read_rows(restarted / CONVERGENCE_FILE)[1], CONVERGENCE_FILE,
                        len(cycles) - len(after))
    snapshots = read_snapshots(full / FIELDS_FILE)
    # The time of `step` (10 digits in the CSV: enough to tell steps apart).
    T_step = float(read_rows(full / CSV_FILES[0])[1][step - 1].split(",")[0])
    after = {t: v for t, v in snapshots.items() if float(t) > T_step}
    out += compare_snapshots(after, read_snapshots(restarted / FIELDS_FILE), FIELDS_FILE)
    out += compare_json(read_run(full / RUN_FILE)["results"],
                        read_run(restarted / RUN_FILE)["results"], "run.json results")
    return out
