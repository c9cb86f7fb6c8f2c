#!/usr/bin/python3
"""The map of cases (issue 9, "Robust over the parameter range"): runs ehlsim on a grid of
Moes parameters M x L plus Roelands/Dowson-Higginson and waviness cases, one run at a time with
one thread, and records how each run ends.

    /usr/bin/python3 scripts/case_map.py [--grid 65] [--out map-65] [--binary build/apps/ehlsim]
                                         [--timeout 900] [--only NAME_SUBSTRING]

Writes OUT/map.csv (one row per case), OUT/map.md (the markdown table of docs/validation.md)
and OUT/map.png (outcome over M and L, rebound speed).  A run that warns that its domain is too
small (results.warnings; docs/usage.md, "How a run ends") has its edge impulse in the table and
a ring in the figure.  Each case runs into OUT/runs/<name>/;
its stderr is kept in OUT/runs/<name>.err.  Debian's python3 with numpy and matplotlib.
"""
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

M_VALUES = [1, 2, 3, 5, 10, 20, 50, 100, 200, 500, 1000]
L_VALUES = [0, 5, 10, 20]
# Paths from the repository, so that the script runs from any directory.
ROOT = Path(__file__).resolve().parent.parent
ROELANDS = str(ROOT / "examples" / "roelands-dh.toml")
BINARY = str(ROOT / "build" / "apps" / "ehlsim")


def cases():
    """(name, config file or None, overrides, group) of every case of the map."""
    out = []
    for L in L_VALUES:
        for M in M_VALUES:
            out.append((f"M{M}_L{L}", None, [f"case.M={M}", f"case.L={L}"], "barus"))
    for M in [10, 100, 1000]:
        out.append((f"roelands_dh_M{M}", ROELANDS, [f"case.M={M}"], "roelands-dh"))
    # The lubricant of roelands-dh.toml with its own z: the file's case.L would contradict it.
    out.append(("roelands_dh_z1e6", None, ["lubricant.viscosity=roelands",
                                           "lubricant.density=dowson-higginson",
                                           "lubricant.eta0=0.04", "lubricant.ph_star=1e9",
                                           "lubricant.z=1e6"], "roelands-dh"))
    for name, amp, wl, angle in [("wavy_x_A0.02", 0.02, 0.5, 0), ("wavy_x_A0.1", 0.1, 0.5, 0),
                                 ("wavy_45deg_A0.02", 0.02, 0.5, 45),
                                 ("wavy_30deg_A0.1", 0.1, 0.5, 30),
                                 ("wavy_x_A0.5_wl1", 0.5, 1.0, 0)]:
        out.append((name, None, [f"surface.waviness_amplitude={amp}",
                                 f"surface.waviness_wavelength={wl}",
                                 f"surface.waviness_angle_deg={angle}"], "waviness"))
    for delta0 in [2, 4]:
        out.append((f"M1_L10_Delta0_{delta0}", None, ["case.M=1", "case.L=10",
                                                      f"time.Delta0={delta0}"], "start"))
    out.append(("rigid_M1_L0", None, ["case.M=1", "case.L=0", "body.elastic=false"], "rigid"))
    out.append(("rigid_M10_L0", None, ["case.M=10", "case.L=0", "body.elastic=false"], "rigid"))
    out.append(("M10000_L10", None, ["case.M=10000"], "probe"))
    return out


def run_case(binary, grid, run_dir, config, overrides, timeout, mode="impact"):
    """Runs one case (an impact, or `mode`) on one thread: exit code ("timeout" if killed),
    stderr as written, seconds."""
    args = [binary, mode, "--quiet", "--out", run_dir]
    if config:
        args.insert(2, config)
    for o in overrides + [f"grid.points={grid}"]:
        args += ["--set", o]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    start = time.monotonic()
    try:
        p = subprocess.run(args, capture_output=True, text=True, timeout=timeout, env=env)
        code, err = p.returncode, p.stderr
    except subprocess.TimeoutExpired:
        code, err = "timeout", f"killed after {timeout} s"
    return code, err, time.monotonic() - start


def record(name, group, code, err, seconds, run_dir):
    row = {"case": name, "group": group, "exit": code, "outcome": "", "T_end": "",
           "T_lift_off": "", "rebound_speed": "", "max_force": "", "min_h": "", "steps": "",
           "retried": "", "unconverged": "", "edge_impulse": "", "warned": "",
           "seconds": f"{seconds:.1f}", "message": err}
    path = os.path.join(run_dir, "run.json")
    if code == 0 and os.path.exists(path):
        r = json.load(open(path))["results"]
        row["outcome"] = r.get("outcome", "lift_off" if r["lifted_off"] else "t_end")
        row["T_end"] = f"{r['T_final']:.4f}"
        if r["T_lift_off"] is not None:
            row["T_lift_off"] = f"{r['T_lift_off']:.4f}"
        if r["rebound_speed"] is not None:
            row["rebound_speed"] = f"{r['rebound_speed']:.4g}"
        row["max_force"] = f"{r['max_force']:.4g}"
        row["steps"], row["retried"] = r["steps"], r["retried_steps"]
        row["unconverged"] = r["unconverged_steps"]
        row["edge_impulse"] = f"{r['edge_impulse']:.4f}"
        # The domain's warning (a wavy surface's note on the spike analysis is not one).
        row["warned"] = "yes" if any("domain's edges" in w for w in r["warnings"]) else ""
        series = os.path.join(run_dir, "timeseries.csv")
        with open(series) as f:
            mins = [float(line.split(",")[5]) for line in list(f)[1:]]
        row["min_h"] = f"{min(mins):.3g}" if mins else ""
    elif code == 1:
        row["outcome"] = "failed"
    else:
        row["outcome"] = "killed" if code == "timeout" else f"exit {code}"
    return row


FIELDS = ["case", "group", "exit", "outcome", "T_end", "T_lift_off", "rebound_speed",
          "max_force", "min_h", "steps", "retried", "unconverged", "edge_impulse", "warned",
          "seconds", "message"]


def write_table(rows, path, grid):
    head = ["case", "exit", "outcome", "lift-off T", "rebound speed", "max force", "min h_min",
            "steps", "retried", "unconverged", "edge impulse", "domain warning", "s",
            "message (exit 1)"]
    with open(path, "w") as f:
        f.write(f"| {' | '.join(head)} |\n|{'---|' * len(head)}\n")
        for r in rows:
            message = r["message"].replace("ehlsim: error: ", "").replace("|", "/")
            cells = [r["case"], str(r["exit"]), r["outcome"], r["T_lift_off"], r["rebound_speed"],
                     r["max_force"], r["min_h"], str(r["steps"]), str(r["retried"]),
                     str(r["unconverged"]), r["edge_impulse"], r["warned"], r["seconds"],
                     message]
            f.write(f"| {' | '.join(cells)} |\n")


COLOURS = {"lift_off": "tab:green", "at_rest": "tab:blue", "t_end": "tab:grey",
           "failed": "tab:red", "killed": "black"}


def plot(rows, path, grid):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    by_name = {r["case"]: r for r in rows}
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.6))
    for k, L in enumerate(L_VALUES):
        for i, M in enumerate(M_VALUES):
            r = by_name.get(f"M{M}_L{L}")
            if r is None:
                continue
            colour = COLOURS.get(r["outcome"], "tab:orange")
            unconverged = r["unconverged"] not in ("", 0)
            left.scatter(i, k, s=260, color=colour, marker="s" if not unconverged else "D",
                         edgecolors="k")
            if r["warned"]:
                left.scatter(i, k, s=560, facecolors="none", edgecolors="tab:orange",
                             linewidths=1.8)
            label = r["rebound_speed"] or {"failed": "exit 1", "killed": "cap"}.get(
                r["outcome"], r["outcome"])
            left.annotate(label, (i, k), xytext=(0, 13), textcoords="offset points",
                          ha="center", fontsize=7)
    left.set_xticks(range(len(M_VALUES)), [str(m) for m in M_VALUES])
    left.set_yticks(range(len(L_VALUES)), [str(l) for l in L_VALUES])
    left.set_ylim(-0.6, len(L_VALUES) - 0.3)
    left.set_xlabel("M")
    left.set_ylabel("L")
    left.set_title(f"outcome on {grid}^2 (label: rebound speed; diamond: unconverged steps;\n"
                   "orange ring: warns that the domain is too small)", fontsize=9)
    for outcome, colour in COLOURS.items():
        left.scatter([], [], color=colour, marker="s", edgecolors="k", label=outcome)
    left.legend(fontsize=7, loc="lower left", ncol=5)
    for L in L_VALUES:
        ms, vs = [], []
        for M in M_VALUES:
            r = by_name.get(f"M{M}_L{L}")
            if r and r["rebound_speed"]:
                ms.append(M)
                vs.append(float(r["rebound_speed"]))
        right.plot(ms, vs, "o-", label=f"L = {L}")
    right.set_xscale("log")
    right.set_xlabel("M")
    right.set_ylabel("rebound speed / V0")
    right.set_title("rebound speed at lift-off (Barus, incompressible)", fontsize=9)
    right.axhline(1.0, color="k", lw=0.6, ls=":")
    right.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=65)
    ap.add_argument("--out", default=None)
    ap.add_argument("--binary", default=BINARY)
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--only", default="")
    a = ap.parse_args()
    out = a.out or f"map-{a.grid}"
    os.makedirs(os.path.join(out, "runs"), exist_ok=True)
    rows = []
    for name, config, overrides, group in cases():
        if a.only and a.only not in name:
            continue
        run_dir = os.path.join(out, "runs", name)
        shutil.rmtree(run_dir, ignore_errors=True)
        code, err, seconds = run_case(a.binary, a.grid, run_dir, config, overrides, a.timeout)
        err = err.strip()
        with open(run_dir + ".err", "w") as f:
            f.write(err + "\n")
        rows.append(record(name, group, code, err, seconds, run_dir))
        r = rows[-1]
        print(f"{name:20s} exit {code!s:7s} {r['outcome']:9s} lift-off {r['T_lift_off']:7s} "
              f"V {r['rebound_speed']:8s} retried {r['retried']!s:3s} unconv "
              f"{r['unconverged']!s:3s} edge {r['edge_impulse']:6s} {seconds:6.1f} s {err[:90]}",
              flush=True)
    with open(os.path.join(out, "map.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        w.writerows(rows)
    write_table(rows, os.path.join(out, "map.md"), a.grid)
    if not a.only:
        plot(rows, os.path.join(out, "map.png"), a.grid)
    return 0


if __name__ == "__main__":
    sys.exit(main())
