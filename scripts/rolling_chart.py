#!/usr/bin/env python3
"""The classic film-thickness chart of the rolling point contact: ehlsim's
central film Hc in Moes units against M, one line per L, beside the
Nijenbanning-Venner-Moes formula (ehlsim's run.json carries both).

    /usr/bin/python3 scripts/rolling_chart.py --grid 257 [--out DIR] [--ehlsim BIN]
                                              [--elliptic] [--set KEY=VALUE]...

Writes DIR/rolling_chart.md (the table), DIR/rolling_chart.json and
DIR/rolling_chart.png.  A case that fails (exit 1) is listed with its reason.
"""
import argparse
import json
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
M_VALUES = [10, 20, 50, 100, 200, 500, 1000]
L_VALUES = [5, 10, 20]


def run_case(ehlsim, grid, M, L, D, work, overrides=()):
    out = Path(work) / f"M{M}_L{L}_D{D}"
    cmd = [ehlsim, "rolling", "--quiet", "--set", f"grid.points={grid}", "--set", f"case.M={M}",
           "--set", f"case.L={L}", "--set", f"case.D={D}", "--out", str(out)]
    for assignment in overrides:
        cmd += ["--set", assignment]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return {"M": M, "L": L, "D": D, "exit": p.returncode, "error": p.stderr.strip()}
    run = json.loads((out / "run.json").read_text())
    r = run["results"]
    return {"M": M, "L": L, "D": D, "exit": 0, "Hc_moes": r["Hc_moes"], "Hm_moes": r["Hm_moes"],
            "nvm": r["Hc_moes_nvm"], "deviation": r["Hc_deviation_from_nvm"],
            "cycles": r["cycles"], "work": r["work_units"], "wall": run["wall_seconds"]}


def table(rows, grid):
    lines = [f"| M | L | D | Hc ehlsim ({grid}^2) | Hc NVM | deviation | Hm ehlsim | cycles |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["exit"]:
            lines.append(f"| {r['M']} | {r['L']} | {r['D']} | exit {r['exit']}: {r['error']} "
                         "| | | | |")
        else:
            lines.append(f"| {r['M']} | {r['L']} | {r['D']} | {r['Hc_moes']:.3f} | "
                         f"{r['nvm']:.3f} | {100 * r['deviation']:+.1f} % | "
                         f"{r['Hm_moes']:.3f} | {r['cycles']} |")
    return "\n".join(lines) + "\n"


def chart(rows, grid, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 5))
    for k, L in enumerate(L_VALUES):
        colour = f"C{k}"
        ok = [r for r in rows if r["L"] == L and r["D"] == 1 and not r["exit"]]
        ax.plot([r["M"] for r in ok], [r["nvm"] for r in ok], "-", color=colour,
                label=f"NVM formula, L = {L}")
        ax.plot([r["M"] for r in ok], [r["Hc_moes"] for r in ok], "o", color=colour,
                label=f"ehlsim {grid}$^2$, L = {L}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("M")
    ax.set_ylabel("$H_c$ (Moes units, $h_c / R_x\\, U^{-1/2}$)")
    ax.set_title("Central film of the rolling point contact (D = 1)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--grid", type=int, default=257)
    parser.add_argument("--out", default="rolling-chart")
    parser.add_argument("--ehlsim", default=str(ROOT / "build" / "apps" / "ehlsim"))
    parser.add_argument("--elliptic", action="store_true", help="also D = 0.5 and 2 at M = 100")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a further override of every case (repeatable)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as work:
        cases = [(M, L, 1) for L in L_VALUES for M in M_VALUES]
        if args.elliptic:
            cases += [(M, 10, D) for D in (0.5, 2) for M in (20, 100)]
        for M, L, D in cases:
            rows.append(run_case(args.ehlsim, args.grid, M, L, D, work, args.set))
            print(rows[-1], flush=True)
    (out / "rolling_chart.json").write_text(json.dumps(rows, indent=1))
    (out / "rolling_chart.md").write_text(table(rows, args.grid))
    chart(rows, args.grid, out / "rolling_chart.png")


if __name__ == "__main__":
    main()
