#!/usr/bin/env python3
"""Figures of one `ehlsim rolling` run, as the EHL literature draws them:
contours of P and H over the contact, and the centre-line profiles of P and H
along Y = 0 and across the contact at X = X(Hm).

    /usr/bin/python3 scripts/plot_rolling.py RUN_DIR [--out FILE.png]

Reads RUN_DIR/fields.nc (with ncdump, no NetCDF Python module needed),
profile_x.csv, profile_y.csv and run.json.
"""
import argparse
import csv
import json
import re
import subprocess
from pathlib import Path


def read_fields(path):
    text = subprocess.run(["ncdump", "-v", "x,y,P,H", str(path)], check=True,
                          capture_output=True, text=True).stdout.split("data:", 1)[1]
    values = {name: [float(v) for v in body.replace("\n", " ").split(",")]
              for name, body in re.findall(r"(\w+) =([^;]*);", text)}
    nx, ny = len(values["x"]), len(values["y"])
    grid = lambda flat: [flat[j * nx:(j + 1) * nx] for j in range(ny)]
    return values["x"], values["y"], grid(values["P"]), grid(values["H"])


def read_csv(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("run_dir")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(args.run_dir)
    run = json.loads((run_dir / "run.json").read_text())
    r, case = run["results"], run["parameters"]["case"]
    x, y, P, H = read_fields(run_dir / "fields.nc")
    along_x, along_y = read_csv(run_dir / "profile_x.csv"), read_csv(run_dir / "profile_y.csv")

    fig, axes = plt.subplots(2, 2, figsize=(11, 9))
    window = dict(xlim=(-2.0, 1.5), ylim=(-1.5, 1.5))
    c = axes[0, 0].contourf(x, y, P, levels=20, cmap="viridis")
    fig.colorbar(c, ax=axes[0, 0], label="P")
    axes[0, 0].set(title="pressure P", xlabel="X", ylabel="Y", **window)
    c = axes[0, 1].contour(x, y, H, levels=[r["Hm"] * f for f in (1.05, 1.2, 1.5, 2, 3, 5, 8)],
                           cmap="plasma")
    axes[0, 1].clabel(c, fontsize=7, fmt="%.3g")
    axes[0, 1].set(title="film thickness H (contours)", xlabel="X", ylabel="Y", **window)
    for ax in axes[0]:
        ax.set_aspect("equal")
    ax = axes[1, 0]
    ax.plot(along_x["X"], along_x["P"], label="P")
    ax.set(xlabel="X", ylabel="P", title="along Y = 0", xlim=(-2.5, 1.5))
    twin = ax.twinx()
    twin.plot(along_x["X"], along_x["H"], "C1", label="H")
    twin.set(ylabel="H", ylim=(0, 4 * r["Hc"]))
    ax = axes[1, 1]
    ax.plot(along_y["Y"], along_y["P"], label="P")
    ax.set(xlabel="Y", ylabel="P", title=f"across, at X = X(Hm) = {r['X_Hm']:.3g}", xlim=(-1.5, 1.5))
    twin = ax.twinx()
    twin.plot(along_y["Y"], along_y["H"], "C1", label="H")
    twin.set(ylabel="H", ylim=(0, 4 * r["Hc"]))
    fig.suptitle(f"ehlsim rolling: M = {case['M']:.4g}, L = {case['L']:.4g}, D = {case['D']:.3g}; "
                 f"Hc = {r['Hc']:.4g} ({r['Hc_moes']:.3g} Moes, NVM {r['Hc_moes_nvm']:.3g}), "
                 f"Hm = {r['Hm']:.4g}")
    fig.tight_layout()
    out = Path(args.out) if args.out else run_dir / "rolling.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
