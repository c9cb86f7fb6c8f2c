#!/usr/bin/env python3
"""Random in-range impacts or rolling contacts, run the way a hostile user would, each
checked for an honest end (docs/validation.md, "Random cases").

    /usr/bin/python3 scripts/random_cases.py [--mode impact|rolling] [--seed 11] [--cases 60]
                                             [--grids 65,129] [--max-M 2000]
                                             [--out random-cases] [--binary build/apps/ehlsim]

An impact draws M (log-uniform 0.5 to 2000), L (0 to 25), Delta0 (0.5 to 3), V0 (0.3 to 2)
and a grid of --grids (by default 65^2 or 129^2); 30 % add waviness (amplitude to 0.3,
wavelength 0.3 to 2, any angle), 25 % Roelands, 25 % Dowson-Higginson, 10 % a rigid ball.
A case is a defect when: the exit code is not 0, 1 or 2; an error is not one line starting
"ehlsim: error:" (exit 1: naming the time step); an exit 0 leaves a non-finite value or a
negative film in timeseries.csv, a rebound faster than 1.03 sqrt(1 + E) V0 (E: the elastic
energy of the film at T = 0 over V0^2 / 2), a start with E > 5 % and no warning, or counts its
unconverged steps other than timeseries.csv shows.

A rolling contact draws M (log-uniform 1 to --max-M, by default 2000), L (0 to 25), D
(log-uniform 0.25 to 4) and a grid of --grids; 25 % move the domain's edges (inlet 2.5 to 6
radii, outlet 1 to 3, square cells), 20 % another solver.tolerance (1e-6 to 1e-3), 25 %
Roelands, 25 % Dowson-Higginson, 10 % rigid bodies.  Its defects: those of an error as above
(exit 1 need not name a time step: there is none, but it says what to try: more points, a
larger domain, more cycles or why more will not help, or the bound of a rigid piezoviscous
film), and for an exit 0 a non-finite result, a residual or force error above the tolerance,
a minimum film that is not positive or above the central one, or an elastic Hc more than 15 %
from the Nijenbanning-Venner-Moes formula without a warning.

One thread, one case at a time; prints one line per case, the defects last, and exits 1 if
there are any.
"""
import argparse
import csv
import json
import math
import os
import random
import shutil
import sys

from case_map import BINARY, run_case


def lubricant_sets(rng):
    sets = []
    if rng.random() < 0.25:
        sets += ["lubricant.viscosity=roelands", "lubricant.eta0=0.04", "lubricant.ph_star=1e9"]
    if rng.random() < 0.25:
        sets += ["lubricant.density=dowson-higginson"]
        if "lubricant.ph_star=1e9" not in sets:
            sets += ["lubricant.ph_star=1e9"]
    if rng.random() < 0.1:
        sets += ["body.elastic=false"]
    return sets


def draw_rolling(rng, grids, max_m):
    """A grid and the --set overrides of one random rolling contact."""
    grid = rng.choice(grids)
    sets = [f"case.M={math.exp(rng.uniform(math.log(1), math.log(max_m))):.4g}",
            f"case.L={rng.uniform(0, 25):.3g}",
            f"case.D={math.exp(rng.uniform(math.log(0.25), math.log(4))):.3g}"]
    if rng.random() < 0.25:
        x_min, x_max = -rng.uniform(2.5, 6), rng.uniform(1, 3)
        half = (x_max - x_min) / 2
        sets += [f"grid.x_min={x_min:.17g}", f"grid.x_max={x_max:.17g}",
                 f"grid.y_min={-half:.17g}", f"grid.y_max={half:.17g}"]
    if rng.random() < 0.2:
        sets += [f"solver.tolerance={10 ** rng.uniform(-6, -3):.3g}"]
    return grid, sets + lubricant_sets(rng)


def draw_impact(rng, grids, _max_m):
    """A grid and the --set overrides of one random impact."""
    grid = rng.choice(grids)
    sets = [f"case.M={math.exp(rng.uniform(math.log(0.5), math.log(2000))):.4g}",
            f"case.L={rng.uniform(0, 25):.3g}",
            f"time.Delta0={rng.uniform(0.5, 3):.3g}",
            f"time.V0={rng.uniform(0.3, 2):.3g}"]
    if rng.random() < 0.3:
        sets += [f"surface.waviness_amplitude={rng.uniform(0, 0.3):.3g}",
                 f"surface.waviness_wavelength={rng.uniform(0.3, 2):.3g}",
                 f"surface.waviness_angle_deg={rng.uniform(0, 90):.3g}"]
    return grid, sets + lubricant_sets(rng)


# What a rolling contact's exit 1 suggests: more points, a larger or smaller domain, more
# cycles or the other deformation update, or (rigid bodies) the bound on alpha_bar; or that
# no grid resolves it.
ROLLING_HINTS = ("use more points", "extend it", "extend the domain", "smaller domain",
                 "may converge it", "bound on alpha_bar", "more cycles will not converge it",
                 "no grid resolves", "no domain holds")


def error_defect(code, err, mode):
    """What is wrong with how a run ended, before its outputs are read."""
    if code not in (0, 1, 2):
        return f"exit code {code}"
    if code == 0:
        return ""
    if not (err.count("\n") == 1 and err.startswith("ehlsim: error: ")):
        return "error is not one line"
    if mode == "impact" and code == 1 and "time step" not in err:
        return "exit 1 without a time step"
    if mode == "rolling" and code == 1 and not any(hint in err for hint in ROLLING_HINTS):
        return "exit 1 without a hint what to try"
    return ""


def value_of(sets, key, default):
    return float(next((s.split("=")[1] for s in sets if s.startswith(key + "=")), default))


def rolling_defects(run_dir, sets):
    r = json.load(open(os.path.join(run_dir, "run.json")))["results"]
    tolerance = value_of(sets, "solver.tolerance", 1e-5)
    keys = ("Hc", "Hm", "H0", "P_max", "residual", "force_error", "Hc_deviation_from_nvm")
    if not all(isinstance(r[k], (int, float)) and math.isfinite(r[k]) for k in keys):
        return "non-finite result"
    problems = []
    if r["residual"] > tolerance or abs(r["force_error"]) > tolerance:
        problems.append(f"residual {r['residual']:g}, force error {r['force_error']:g} "
                        f"above the tolerance {tolerance:g}")
    if not 0 < r["Hm"] <= r["Hc"]:
        problems.append(f"films Hm {r['Hm']:g}, Hc {r['Hc']:g}")
    elastic = "body.elastic=false" not in sets
    if elastic and abs(r["Hc_deviation_from_nvm"]) > 0.15 and not r["warnings"]:
        problems.append(f"Hc {100 * r['Hc_deviation_from_nvm']:+.0f} % from the formula, "
                        "no warning")
    return "; ".join(problems)


def impact_defects(run_dir, sets, tolerance=1e-5):
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
    # The energy of the start: the impact's and what the film at T = 0 stored
    # in the solids (a start that stores more than 5 % of it warns).
    stored = results["initial_elastic_energy"] / (0.5 * v0 * v0)
    if speed is not None and speed > 1.03 * math.sqrt(1.0 + stored) * v0:
        problems.append(f"rebound {speed:g} above sqrt(1 + {stored:.3g}) V0, V0 = {v0:g}")
    if stored > 0.05 and not any("the film at T = 0 stores" in w for w in results["warnings"]):
        problems.append(f"the start stores {stored:.3g} of the impact energy without a warning")
    above = sum(1 for r in rows if float(r["residual"]) > tolerance)
    if above != results["unconverged_steps"]:
        problems.append(f"{above} steps above the tolerance, {results['unconverged_steps']} counted")
    return "; ".join(problems)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mode", choices=("impact", "rolling"), default="impact")
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--cases", type=int, default=60)
    parser.add_argument("--out", default="random-cases")
    parser.add_argument("--binary", default=BINARY)
    parser.add_argument("--grids", default="65,129",
                        help="points per side to draw from, comma-separated")
    parser.add_argument("--max-M", type=float, default=2000.0,
                        help="the largest load M a rolling contact draws")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    grids = [int(g) for g in args.grids.split(",")]
    defects = []
    for i in range(args.cases):
        draw = draw_impact if args.mode == "impact" else draw_rolling
        grid, sets = draw(rng, grids, args.max_M)
        run_dir = os.path.join(args.out, f"{args.mode}_{args.seed}_{i}")
        shutil.rmtree(run_dir, ignore_errors=True)
        code, err, _ = run_case(args.binary, grid, run_dir, None, sets, 600, args.mode)
        problem = error_defect(code, err, args.mode)
        if code == 0 and not problem:
            defects_of = impact_defects if args.mode == "impact" else rolling_defects
            problem = defects_of(run_dir, sets)
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
