#!/usr/bin/env python3
"""Random in-range impacts, run the way a hostile user would, each checked for an
honest end (docs/validation.md, "Random cases").

    /usr/bin/python3 scripts/random_cases.py [--seed 11] [--cases 60] [--out random-cases]
                                             [--binary build/apps/ehlsim]

Each case draws M (log-uniform 0.5 to 2000), L (0 to 25), Delta0 (0.5 to 3), V0 (0.3 to 2)
and a 65^2 or 129^2 grid; 30 % add waviness (amplitude to 0.3, wavelength 0.3 to 2, any
angle), 25 % Roelands, 25 % Dowson-Higginson, 10 % a rigid ball.  A case is a defect when:
the exit code is not 0, 1 or 2; an error is not one line starting "ehlsim: error:" (exit 1:
naming the time step); an exit 0 leaves a non-finite value or a negative film in
timeseries.csv, a rebound faster than 1.03 V0, or counts its unconverged steps other than
timeseries.csv shows.  One thread, one case at a time; prints one line per case, the
defects last, and exits 1 if there are any.
"""
import argparse
import csv
import json
import math
import os
import random
import shutil
import sys

from case_map import run_case


def draw(rng):
    """A grid and the --set overrides of one random case."""
    grid = rng.choice([65, 129])
    sets = [f"case.M={math.exp(rng.uniform(math.log(0.5), math.log(2000))):.4g}",
            f"case.L={rng.uniform(0, 25):.3g}",
            f"time.Delta0={rng.uniform(0.5, 3):.3g}",
            f"time.V0={rng.uniform(0.3, 2):.3g}"]
    if rng.random() < 0.3:
        sets += [f"surface.waviness_amplitude={rng.uniform(0, 0.3):.3g}",
                 f"surface.waviness_wavelength={rng.uniform(0.3, 2):.3g}",
                 f"surface.waviness_angle_deg={rng.uniform(0, 90):.3g}"]
    if rng.random() < 0.25:
        sets += ["lubricant.viscosity=roelands", "lubricant.eta0=0.04", "lubricant.ph_star=1e9"]
    if rng.random() < 0.25:
        sets += ["lubricant.density=dowson-higginson"]
        if "lubricant.ph_star=1e9" not in sets:
            sets += ["lubricant.ph_star=1e9"]
    if rng.random() < 0.1:
        sets += ["body.elastic=false"]
    return grid, sets


def defects_of(code, err, run_dir, sets, tolerance=1e-5):
    if code not in (0, 1, 2):
        return f"exit code {code}"
    if code != 0:
        shape_ok = err.count("\n") == 1 and err.startswith("ehlsim: error: ")
        if not shape_ok:
            return "error is not one line"
        if code == 1 and "time step" not in err:
            return "exit 1 without a time step"
        return ""
    results = json.load(open(os.path.join(run_dir, "run.json")))["results"]
    rows = list(csv.DictReader(open(os.path.join(run_dir, "timeseries.csv"))))
    problems = []
    values = [float(r[k]) for r in rows for k in ("Delta", "force", "p_max", "h_min")]
    if not all(math.isfinite(v) for v in values):
        problems.append("non-finite state")
    h_min = min(float(r["h_min"]) for r in rows)
    if h_min < 0:
        problems.append(f"negative film {h_min:g}")
    v0 = float(next(s for s in sets if s.startswith("time.V0=")).split("=")[1])
    speed = results.get("rebound_speed")
    if speed is not None and speed > 1.03 * v0:
        problems.append(f"rebound {speed:g} above V0 {v0:g}")
    above = sum(1 for r in rows if float(r["residual"]) > tolerance)
    if above != results["unconverged_steps"]:
        problems.append(f"{above} steps above the tolerance, {results['unconverged_steps']} counted")
    return "; ".join(problems)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--cases", type=int, default=60)
    parser.add_argument("--out", default="random-cases")
    parser.add_argument("--binary", default="build/apps/ehlsim")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    defects = []
    for i in range(args.cases):
        grid, sets = draw(rng)
        run_dir = os.path.join(args.out, f"{args.seed}_{i}")
        shutil.rmtree(run_dir, ignore_errors=True)
        code, err, _ = run_case(args.binary, grid, run_dir, None, sets, timeout=600)
        problem = defects_of(code, err, run_dir, sets)
        line = f"{i} exit {code} | grid.points={grid} {' '.join(sets)} | {err.strip()[:200]}"
        print(line + (f" | DEFECT: {problem}" if problem else ""), flush=True)
        if problem:
            defects.append(line + " | " + problem)
    print(f"{len(defects)} defects in {args.cases} cases")
    for d in defects:
        print(d)
    return 1 if defects else 0


if __name__ == "__main__":
    sys.exit(main())
