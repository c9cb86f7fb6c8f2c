#!/usr/bin/env python3
"""The paper's impact-rolling similarity (section 2; its ref. [9]): at equal
lambda_bar (the same M and L) the impact's central film history h_c(T) and the
steady rolling contact's film H(X) along Y = 0 should look alike, with T in
place of X.  Runs both modes for M = 20 and M = 100 at L = 10 and draws them on
common axes, the impact's time shifted so that its largest force is at X = 0.

    /usr/bin/python3 scripts/similarity.py [--impact-grid 129] [--rolling-grid 257]
                                           [--out docs/figures/rolling] [--ehlsim BIN]
"""
import argparse
import csv
import json
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CASES = [20, 100]
L = 10


def read_csv(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {key: [float(r[key]) for r in rows] for key in rows[0]}


def run(ehlsim, mode, M, grid, out):
    subprocess.run([ehlsim, mode, "--quiet", "--set", f"case.M={M}", "--set", f"case.L={L}",
                    "--set", f"grid.points={grid}", "--out", str(out)], check=True)
    return json.loads((out / "run.json").read_text())


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--impact-grid", type=int, default=129)
    parser.add_argument("--rolling-grid", type=int, default=257)
    parser.add_argument("--out", default=str(ROOT / "docs" / "figures" / "rolling"))
    parser.add_argument("--ehlsim", default=str(ROOT / "build" / "apps" / "ehlsim"))
    args = parser.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, len(CASES), figsize=(11, 4.2))
    summary = {}
    with tempfile.TemporaryDirectory() as work:
        for ax, M in zip(axes, CASES):
            impact_run = run(args.ehlsim, "impact", M, args.impact_grid, Path(work) / f"i{M}")
            rolling_run = run(args.ehlsim, "rolling", M, args.rolling_grid, Path(work) / f"r{M}")
            series = read_csv(Path(work) / f"i{M}" / "timeseries.csv")
            profile = read_csv(Path(work) / f"r{M}" / "profile_x.csv")
            T_peak = impact_run["results"]["T_max_force"]
            shifted = [T - T_peak for T in series["T"]]
            ax.plot(profile["X"], profile["H"], "-", label=f"rolling: H(X, 0), {args.rolling_grid}$^2$")
            ax.plot(shifted, series["h_center"], "--",
                    label=f"impact: $h_c$(T - {T_peak:.2f}), {args.impact_grid}$^2$")
            ax.set_xlim(-3, 2.2)
            ax.set_ylim(0, 1.5)
            ax.set_xlabel("X (rolling)  |  T - T(max force) (impact)")
            ax.set_ylabel("H")
            ax.set_title(f"M = {M}, L = {L} (same lambda_bar)")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
            r = rolling_run["results"]
            summary[M] = {"rolling_Hc": r["Hc"], "rolling_Hm": r["Hm"],
                          "impact_min_h_center": impact_run["results"]["min_h_center"],
                          "impact_T_max_force": T_peak,
                          "impact_h_center_at_max_force":
                              series["h_center"][series["T"].index(T_peak)]}
    fig.tight_layout()
    fig.savefig(out / "similarity.png", dpi=120)
    (out / "similarity.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
