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


def profile(ax, line, coordinate, title, xlim, Hc):
    """P (left axis) and H (right axis) along one line, told apart by colour and legend."""
    ax.plot(line[coordinate], line["P"], "C0", label="P (left)")
    ax.set(xlabel=coordinate, title=title, xlim=xlim)
    ax.set_ylabel("P", color="C0")
    twin = ax.twinx()
    twin.plot(line[coordinate], line["H"], "C1", label="H (right)")
    twin.set(ylim=(0, 4 * Hc))
    twin.set_ylabel("H", color="C1")
    ax.legend(handles=ax.get_lines() + twin.get_lines(), loc="upper left", fontsize=8)


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
    profile(axes[1, 0], along_x, "X", "along Y = 0", (-2.5, 1.5), r["Hc"])
    profile(axes[1, 1], along_y, "Y", f"across, at X = X(Hm) = {r['X_Hm']:.3g}", (-1.5, 1.5),
            r["Hc"])
    fig.suptitle(f"ehlsim rolling: M = {case['M']:.4g}, L = {case['L']:.4g}, D = {case['D']:.3g}; "
                 f"Hc = {r['Hc']:.4g} ({r['Hc_moes']:.3g} Moes, NVM {r['Hc_moes_nvm']:.3g}), "
                 f"Hm = {r['Hm']:.4g}")
    fig.tight_layout()
    out = Path(args.out) if args.out else run_dir / "rolling.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
