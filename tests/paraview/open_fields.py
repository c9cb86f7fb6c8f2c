"""fields.nc opens in ParaView with its true coordinates and its snapshots as time steps.

Run by pvbatch under xvfb-run (for the picture), through run.sh:
    xvfb-run -a pvbatch open_fields.py EHLSIM OUT_DIR [impact|rolling]

Runs a small impact (or steady rolling contact: one snapshot on the
non-centred domain X in [-4.5, 1.5]) into OUT_DIR/run, opens its fields.nc with ParaView's
NetCDF (CF) reader and checks against the file itself (read with ncdump,
independently of ParaView) and run.json:
- the spatial bounds are the true X, Y range (not the indices 0..n-1);
- there are as many time steps as snapshots, at the stored times T;
- the range of P at one time step is the range of the stored values;
then saves OUT_DIR/fields_P.png (P at the time of the largest pressure).
Exits 1 naming every failed check.
"""
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

from paraview import servermanager
from paraview.simple import (ColorBy, CreateRenderView, Delete, Disconnect,
                             GetColorTransferFunction, NetCDFReader, ResetCamera, SaveScreenshot,
                             Show, Text)

# Small cases: the impact with several snapshots, 33^2 to lift-off in about a
# second; the rolling contact, 33^2 in a fraction of a second.
CASES = {"impact": ["--set", "grid.points=33", "--set", "output.snapshot_every=5"],
         "rolling": ["--set", "grid.points=33"]}
# ncdump's digits that give every double back exactly.
NCDUMP_PRECISION = "9,17"
# Relative tolerance between ParaView's numbers and the file's (both doubles).
TOLERANCE = 1e-12
PICTURE_SIZE = [900, 760]


def run_case(ehlsim, mode, run_dir):
    """run.json of the run, with "expected_bounds" [x0, x1, y0, y1] and "snapshots" added."""
    shutil.rmtree(run_dir, ignore_errors=True)
    subprocess.run([ehlsim, mode, *CASES[mode], "--out", str(run_dir), "--quiet"], check=True)
    run = json.loads((run_dir / "run.json").read_text())
    if mode == "impact":
        half = run["grid"]["half_width"]
        run["expected_bounds"] = [-half, half, -half, half]
        run["snapshots"] = run["files"]["snapshots"]
    else:
        g = run["parameters"]["grid"]
        run["expected_bounds"] = [g["x_min"], g["x_max"], g["y_min"], g["y_max"]]
        run["snapshots"] = 1
    return run


def read_with_ncdump(path):
    """{name: [values]} of the variables time, y, x and P (P flattened)."""
    text = subprocess.run(["ncdump", "-p", NCDUMP_PRECISION, "-v", "time,y,x,P", str(path)],
                          check=True, capture_output=True, text=True).stdout
    data = text.split("data:", 1)[1]
    return {name: [float(v) for v in values.replace("\n", " ").split(",")]
            for name, values in re.findall(r"(\w+) =([^;]*);", data)}


def close(a, b):
    return abs(a - b) <= TOLERANCE * max(1.0, abs(a), abs(b))


def all_close(a, b):
    return len(a) == len(b) and all(close(x, y) for x, y in zip(a, b))


def check_reader(reader, stored, run):
    """Compares what ParaView reads with the stored values: (time step checked, failures)."""
    failures = []
    times = list(reader.TimestepValues)
    snapshots = run["snapshots"]
    if len(times) != snapshots or not all_close(times, stored["time"]):
        failures.append(f"time steps {times}: expected the {snapshots} stored times "
                        f"{stored['time']}")
    # The snapshot with the largest pressure: its range differs from the others'.
    size = len(stored["x"]) * len(stored["y"])
    per_snapshot = [stored["P"][k * size:(k + 1) * size] for k in range(len(stored["time"]))]
    k = max(range(len(per_snapshot)), key=lambda k: max(per_snapshot[k]))
    T = stored["time"][k]
    expected_range = [min(per_snapshot[k]), max(per_snapshot[k])]
    reader.UpdatePipeline(T)
    data = servermanager.Fetch(reader)
    expected = run["expected_bounds"]
    bounds = list(data.GetBounds())[:4]
    if not all_close(bounds, expected) or not all_close(
            bounds, [stored["x"][0], stored["x"][-1], stored["y"][0], stored["y"][-1]]):
        failures.append(f"bounds {bounds}: expected [X0, X1, Y0, Y1] = {expected}")
    array = data.GetPointData().GetArray("P")
    if array is None:
        failures.append("no point array P")
    elif not all_close(array.GetRange(), expected_range):
        failures.append(f"P range at T = {T}: {array.GetRange()}, file: {expected_range}")
    return T, failures


def save_picture(reader, T, view, path):
    view.ViewSize = PICTURE_SIZE
    view.ViewTime = T
    view.InteractionMode = "2D"
    view.OrientationAxesVisibility = 0
    view.AxesGrid.Visibility = 1
    view.AxesGrid.XTitle = "X"
    view.AxesGrid.YTitle = "Y"
    display = Show(reader, view)
    display.SetRepresentationType("Surface")
    display.Ambient, display.Diffuse = 1.0, 0.0  # the colours of the colour bar, unshaded
    ColorBy(display, ("POINTS", "P"))
    display.RescaleTransferFunctionToDataRange(True, False)
    display.SetScalarBarVisibility(view, True)
    GetColorTransferFunction("P").ApplyPreset("Viridis (matplotlib)", True)
    Show(Text(Text=f"ehlsim fields.nc: P at T = {T:.6g}"), view)
    ResetCamera(view)
    path.unlink(missing_ok=True)
    SaveScreenshot(str(path), view, ImageResolution=PICTURE_SIZE)
    return [] if path.exists() and path.stat().st_size > 0 else [f"no picture {path}"]


def main():
    ehlsim, out_dir = sys.argv[1], Path(sys.argv[2])
    mode = sys.argv[3] if len(sys.argv) > 3 else "impact"
    out_dir.mkdir(parents=True, exist_ok=True)
    run = run_case(ehlsim, mode, out_dir / "run")
    fields = out_dir / "run" / "fields.nc"
    stored = read_with_ncdump(fields)
    reader = NetCDFReader(FileName=[str(fields)])
    reader.UpdatePipelineInformation()
    picture = out_dir / "fields_P.png"
    view = CreateRenderView()
    try:
        T, failures = check_reader(reader, stored, run)
        failures += save_picture(reader, T, view, picture)
    finally:
        # pvbatch ends with an X error (GLXBadContext, exit code 1) when the
        # interpreter exits with a render window still open.
        Delete(view)
        del view
        Disconnect()
    for failure in failures:
        print(f"FAIL: {failure}")
    print(f"{len(failures)} failure(s); picture: {picture}")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
