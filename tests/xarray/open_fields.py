"""fields.nc opens in xarray as the README says, and holds the fields the run reported.

Run by ctest with Debian's python3 (python3-xarray and python3-netcdf4 come with
scripts/setup.sh):
    /usr/bin/python3 open_fields.py EHLSIM OUT_DIR [impact|rolling]

Runs a small impact (or steady rolling contact) into OUT_DIR/run, then
- runs the README's lines for reading the outputs, as they stand there;
- checks the dimensions (time, y, x) of P and H, the true coordinates (the
  grid's points and bounds of run.json) and the CF attributes;
- checks the fields against the numbers the run printed elsewhere:
  impact: each snapshot's time is a row of timeseries.csv, and its P and H give
  that row's force (h^2 sum P), p_max, p_center, h_center and h_min; P is even
  in X and in Y (a case solved on the quadrant, mirrored);
  rolling: P's largest value and its place, H at the centre, and the force
  error h^2 sum P / (2 pi / 3) - 1 of run.json;
  both: the parameters in the file's attributes are those of run.json.
Exits 1 naming every failed check.
"""
import json
import math
import shutil
import sys
import subprocess
from pathlib import Path

import numpy as np
import xarray as xr

# Small cases, each a second or less: the impact with several snapshots.
CASES = {"impact": ["--set", "grid.points=33", "--set", "output.snapshot_every=5"],
         "rolling": ["--set", "grid.points=33"]}
# timeseries.csv prints 10 significant digits (docs/usage.md, "Outputs").
CSV_TOLERANCE = 1e-9
# Sums of the same doubles in another order.
SUM_TOLERANCE = 1e-12
# The impact's load scale: the Hertz force 2 pi / 3 (docs/model.md).
HERTZ_FORCE = 2.0 * math.pi / 3.0


def run_case(ehlsim, mode, run_dir):
    shutil.rmtree(run_dir, ignore_errors=True)
    subprocess.run([ehlsim, mode, *CASES[mode], "--out", str(run_dir), "--quiet"], check=True)
    return json.loads((run_dir / "run.json").read_text())


def readme_lines(run_dir):
    """README.md's lines under "Reading them" (an impact's), with run/ replaced by run_dir."""
    run = json.load(open(run_dir / "run.json"))
    print(run["results"]["T_lift_off"], run["results"]["rebound_speed"])
    ts = np.genfromtxt(run_dir / "timeseries.csv", delimiter=",", names=True)
    ds = xr.open_dataset(run_dir / "fields.nc")
    profile = ds.P.sel(time=3.28125, method="nearest").sel(y=0.0, method="nearest")
    return ts, profile


def near(a, b, tolerance):
    return abs(a - b) <= tolerance * max(1.0, abs(a), abs(b))


def check_layout(ds, run, bounds):
    failures = []
    for name in ("P", "H"):
        if ds[name].dims != ("time", "y", "x"):
            failures.append(f"{name} has dimensions {ds[name].dims}, not (time, y, x)")
        if not ds[name].attrs.get("long_name") or ds[name].attrs.get("units") != "1":
            failures.append(f"{name} lacks long_name or units = 1: {dict(ds[name].attrs)}")
    points = run["parameters"]["grid"]["points"]
    for axis, (low, high) in zip(("x", "y"), (bounds[:2], bounds[2:])):
        values = ds[axis].values
        steps = np.diff(values)
        if len(values) != points or values[0] != low or values[-1] != high or not np.allclose(
                steps, steps[0], rtol=SUM_TOLERANCE, atol=0.0):
            failures.append(f"{axis}: {len(values)} points from {values[0]} to {values[-1]}, "
                            f"expected {points} equally spaced from {low} to {high}")
    if json.loads(ds.attrs["ehlsim_parameters"]) != run["parameters"]:
        failures.append("the attribute ehlsim_parameters differs from run.json's parameters")
    # Every effective parameter is also an attribute of its own (README, "Outputs").
    for section, keys in run["parameters"].items():
        for key, value in keys.items():
            name = f"{section}_{key}"
            if isinstance(value, (int, float)) and not isinstance(value, bool) and (
                    name not in ds.attrs or float(ds.attrs[name]) != value):
                failures.append(f"attribute {name} = {ds.attrs.get(name)}, run.json: {value}")
    return failures


def check_impact(ds, run, ts):
    half = run["grid"]["half_width"]
    failures = check_layout(ds, run, [-half, half, -half, half])
    h2 = run["grid"]["h"] ** 2
    if ds.sizes["time"] != run["files"]["snapshots"]:
        failures.append(f"{ds.sizes['time']} snapshots, run.json says {run['files']['snapshots']}")
    centre = {"y": 0.0, "x": 0.0}
    for T in ds.time.values:
        rows = ts[np.isclose(ts["T"], T, rtol=CSV_TOLERANCE, atol=0.0)]
        if len(rows) != 1:
            failures.append(f"snapshot T = {T} is not one row of timeseries.csv")
            continue
        row, P, H = rows[0], ds.P.sel(time=T), ds.H.sel(time=T)
        found = {"force": h2 * float(P.sum()), "p_max": float(P.max()),
                 "p_center": float(P.sel(centre)), "h_center": float(H.sel(centre)),
                 "h_min": float(H.min())}
        for name, value in found.items():
            if not near(value, float(row[name]), CSV_TOLERANCE):
                failures.append(f"T = {T}: {name} {value} from fields.nc, {row[name]} in "
                                "timeseries.csv")
        if not (np.array_equal(P.values, P.values[::-1, :]) and
                np.array_equal(P.values, P.values[:, ::-1])):
            failures.append(f"T = {T}: P is not even in X and Y")
    return failures


def check_rolling(ds, run):
    g = run["parameters"]["grid"]
    failures = check_layout(ds, run, [g["x_min"], g["x_max"], g["y_min"], g["y_max"]])
    r = run["results"]
    P, H = ds.P.isel(time=0), ds.H.isel(time=0)
    place = P.where(P == P.max(), drop=True)
    if float(P.max()) != r["P_max"] or float(place.x[0]) != r["X_P_max"] or float(
            place.y[0]) != r["Y_P_max"]:
        failures.append(f"largest P {float(P.max())} at ({float(place.x[0])}, "
                        f"{float(place.y[0])}); run.json: {r['P_max']} at ({r['X_P_max']}, "
                        f"{r['Y_P_max']})")
    Hc = float(H.sel(x=r["X_Hc"], y=r["Y_Hc"]))
    if Hc != r["Hc"]:
        failures.append(f"H at the centre {Hc}, run.json's Hc {r['Hc']}")
    h2 = run["grid"]["h"] ** 2
    force_error = h2 * float(P.sum()) / HERTZ_FORCE - 1.0
    if abs(force_error - r["force_error"]) > 1e-9:
        failures.append(f"force error {force_error} from fields.nc, {r['force_error']} in run.json")
    return failures


def main():
    ehlsim, out_dir = sys.argv[1], Path(sys.argv[2])
    mode = sys.argv[3] if len(sys.argv) > 3 else "impact"
    out_dir.mkdir(parents=True, exist_ok=True)
    run_dir = out_dir / "run"
    run = run_case(ehlsim, mode, run_dir)
    ds = xr.open_dataset(run_dir / "fields.nc")
    if mode == "impact":
        ts, profile = readme_lines(run_dir)
        failures = check_impact(ds, run, ts)
        if profile.dims != ("x",) or profile.sizes["x"] != ds.sizes["x"]:
            failures.append(f"the README's profile has dimensions {profile.dims}")
    else:
        failures = check_rolling(ds, run)
    for failure in failures:
        print(f"FAIL: {failure}")
    print(f"{len(failures)} failure(s): {mode}, {ds.sizes['time']} snapshot(s) of "
          f"{ds.sizes['y']} x {ds.sizes['x']} points")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
