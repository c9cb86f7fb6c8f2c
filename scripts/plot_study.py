#!/usr/bin/python3
"""Figures of `ehlsim study` (Lubrecht & Venner 2022, figures 1-6) and the film and force
histories of its cases, as PNG plus the CSV behind each, in FIGURES_DIR (default STUDY_DIR/figures/).

Run with Debian's Python (numpy, matplotlib):
    /usr/bin/python3 scripts/plot_study.py STUDY_DIR [FIGURES_DIR]

Reads, per case STUDY_DIR/M<M>/: timeseries.csv, spike.csv (in-situ, every step),
spike_snapshots.csv, spike_profiles.csv, axis_profiles.csv (`ehlsim spike`), run.json;
STUDY_DIR/dry.csv; and, for the impact-rolling similarity (figure similarity),
STUDY_DIR/rolling_M<M>/profile_x.csv and run.json of the steady rolling contact.  Also writes figures/summary.json with the measured figures quoted in
docs/validation.md (lift-off per M, spike path, V_s ratio, R_s against the dry radius).
"""
import csv
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from study_data import first_unconverged_step, read_csv  # noqa: E402

CASES = [10, 20, 50, 100]          # the paper's M, with L = 10
PROFILE_CASE = 100                 # figures 3, 4, 6: M = 100
COMPARISON_CASE = 10               # figures 1, 2: M = 10 at T = 3.574
COMPARISON_T = 3.574
FIRST_PROFILE_T = 3.223            # figure 3 starts here (the paper's right-most spike)
PAPER_DT = 3.0 / 1024.0           # the paper's time step: dT = dX on 1025^2 over [-1.5, 1.5]
FIG3_INTERVAL = 20 * PAPER_DT      # the paper: "time increments of 20 time steps" (0.0586)
FIG4_EVERY_STEPS = 2               # the paper: "only two time steps" (every snapshot here)
FIG4_WINDOW = 0.13                 # the paper's figure 4 spans T = 4.242 ... 4.371
DETAIL_HALF_WIDTH = 0.15           # figure 2: R_s +- this
PAPER_MAX_DEFORMATION_T = 3.0      # the paper's "maximum deformation point T = 3" (figure 6)
EARLY_WINDOW = 0.1                 # V_s near T = 3: mean over T = 3 +- this
LATE_STEPS = 3                     # V_s just before lift-off: mean of the last 3 spike steps
COMPARISON_TIMES = [3.0, 3.5, 3.75, 4.0]   # R_s against A_dry in summary.json
SIMILARITY_CASES = [20, 100]       # the impact beside the rolling contact at the same M, L = 10
SIMILARITY_X_RANGE = (-3.0, 2.2)   # the rolling X and the impact's T - T(max force)
SIMILARITY_H_MAX = 1.5
DPI = 130


def write_csv(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in r])


def group_by_time(columns, position):
    """{T: (positions, values)} of a long-format profile file."""
    T = columns["T"]
    out = {}
    for t in np.unique(T):
        sel = T == t
        value_name = [k for k in columns if k not in ("T", position)][0]
        out[float(t)] = (columns[position][sel], columns[value_name][sel])
    return out


def load_case(study, M):
    d = os.path.join(study, f"M{M}")
    case = {"M": M, "dir": d}
    case["run"] = json.load(open(os.path.join(d, "run.json")))
    case["dT"] = case["run"]["dT"]
    case["ts"] = read_csv(os.path.join(d, "timeseries.csv"))
    case["spike"] = read_csv(os.path.join(d, "spike.csv"))
    case["radial"] = group_by_time(read_csv(os.path.join(d, "spike_profiles.csv")), "R")
    case["axis"] = group_by_time(read_csv(os.path.join(d, "axis_profiles.csv")), "X")
    case["snapshots"] = read_csv(os.path.join(d, "spike_snapshots.csv"))
    res = case["run"]["results"]
    case["T_lift_off"] = res["T_lift_off"] if res["T_lift_off"] is not None else float("nan")
    truncate_at_divergence(case)
    ts = case["ts"]
    case["T_max_deformation"] = float(ts["T"][np.argmin(ts["Delta"])])
    return case


def truncate_at_divergence(case):
    """Drops every step from the first one the solver did not converge (residual far above
    its tolerance, or non-finite values) on, and records its time in case["T_diverged"]."""
    case["T_diverged"], limit = first_unconverged_step(case["run"], case["ts"])
    if case["T_diverged"] is None:
        return
    T_end = case["T_diverged"] - 1e-9
    print(f"M = {case['M']}: the steps from T = {case['T_diverged']:.4f} on did not converge "
          f"(residual above {limit:g}); they are left out")
    for name in ("ts", "spike", "snapshots"):
        keep = case[name]["T"] < T_end
        case[name] = {k: v[keep] for k, v in case[name].items()}
    for name in ("radial", "axis"):
        case[name] = {t: v for t, v in case[name].items() if t < T_end}


def step_of(T, dT):
    return int(round(T / dT))


def snapshot_at_or_after(case, T):
    times = sorted(t for t in case["radial"] if t >= T - 1e-9)
    return times[0] if times else None


def pressurized_times(case):
    """Snapshot times with pressure left (the lift-off snapshot has none)."""
    return sorted(t for t, (_, p) in case["radial"].items() if np.nanmax(p) > 0)


def fig1_fig2(case, out):
    T = snapshot_at_or_after(case, COMPARISON_T)
    if T is None:
        return None  # the run ended before COMPARISON_T
    R, P_R = case["radial"][T]
    X, P_X = case["axis"][T]
    snaps = case["snapshots"]
    k = int(np.argmin(np.abs(snaps["T"] - T)))
    R_s, X_s = float(snaps["R_s"][k]), float(snaps["X_s"][k])
    rows = [("P_X", float(x), float(p)) for x, p in zip(X, P_X)] + \
           [("P_R_filtered", float(r), float(p)) for r, p in zip(R, P_R)]
    # The detail is centred on the spike, or on the pressure maximum when there is none.
    centre = R_s if math.isfinite(R_s) else float(R[np.nanargmax(P_R)])
    for name, xlim in (("fig1", None), ("fig2", (max(0.0, centre - DETAIL_HALF_WIDTH), centre + DETAIL_HALF_WIDTH))):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        ax.plot(X, P_X, "x", ms=4, color="k", label="P(X), Y = 0")
        ax.plot(R, P_R, "-", color="C0", lw=1.4, label="filtered P(R)")
        if math.isfinite(R_s):
            ax.axvline(R_s, color="C3", lw=0.8, ls="--", label=f"R_s = {R_s:.4f}")
        if math.isfinite(X_s):
            ax.axvline(X_s, color="0.5", lw=0.8, ls=":", label=f"X_s = {X_s:.4f} (grid point)")
        ax.set_xlabel("X, R")
        ax.set_ylabel("P")
        ax.set_title(f"M = {case['M']}, L = 10, T = {T:.4f}" + ("" if xlim is None else ", detail"))
        if xlim is None:
            ax.set_xlim(0, 1.5)
            sel_rows = rows
        else:
            ax.set_xlim(*xlim)
            shown = np.concatenate([P_R[(R >= xlim[0]) & (R <= xlim[1])], P_X[(X >= xlim[0]) & (X <= xlim[1])]])
            if shown.size:
                lo, hi = np.nanmin(shown), np.nanmax(shown)
                ax.set_ylim(lo - 0.1 * (hi - lo + 1e-9), hi + 0.1 * (hi - lo + 1e-9))
            sel_rows = [r for r in rows if xlim[0] <= r[1] <= xlim[1]]
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(out, f"{name}.png"), dpi=DPI)
        plt.close(fig)
        write_csv(os.path.join(out, f"{name}.csv"), ["curve", "position", "P"], sel_rows)
    return {"T": T, "R_s": R_s, "X_s": X_s}


def profile_figure(case, times, name, title, out, xlim=None):
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    cmap = plt.get_cmap("viridis")
    rows = []
    for k, t in enumerate(times):
        R, P = case["radial"][t]
        ax.plot(R, P, lw=1.0, color=cmap(k / max(1, len(times) - 1)), label=f"T = {t:.3f}")
        rows += [(t, float(r), float(p)) for r, p in zip(R, P)]
    ax.set_xlabel("R")
    ax.set_ylabel("filtered P(R)")
    ax.set_title(title)
    ax.set_xlim(*(xlim or (0, 1.2)))
    if len(times) <= 14:
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"{name}.png"), dpi=DPI)
    plt.close(fig)
    write_csv(os.path.join(out, f"{name}.csv"), ["T", "R", "P_filtered"], rows)


def fig3_spacing(live, start):
    """The spacing of fig3's profiles for its title: the paper's where the
    snapshots are fine enough for it, else what they allow (a coarse grid's
    2 steps are longer than the paper's 20)."""
    after = [t for t in live if t >= start]
    if len(after) < 2:
        return f"every $\\Delta T$ = {FIG3_INTERVAL:.4f}"
    apart = sorted(b - a for a, b in zip(after, after[1:]))[(len(after) - 1) // 2]  # the median
    if apart <= FIG3_INTERVAL / 2:
        return f"every $\\Delta T$ = {FIG3_INTERVAL:.4f}"
    return f"nearest to every $\\Delta T$ = {FIG3_INTERVAL:.4f} (the snapshots are {apart:.4f} apart)"


def fig3_fig4(case, out):
    dT = case["dT"]
    live = pressurized_times(case)
    start = snapshot_at_or_after(case, FIRST_PROFILE_T)
    if start is None or not live:
        return None  # the run ended before FIRST_PROFILE_T
    # The paper's spacing in time, 20 of its steps; on a coarser grid that is
    # fewer of ours: the snapshot nearest to each multiple of the interval.
    fig3 = []
    target = start
    while target <= live[-1] + 1e-9:
        nearest = min((t for t in live if t >= start), key=lambda t: abs(t - target))
        if nearest not in fig3:
            fig3.append(nearest)
        target += FIG3_INTERVAL
    if live[-1] not in fig3:
        fig3.append(live[-1])  # the last profile before lift-off, as the paper's 4.365
    profile_figure(case, fig3, "fig3", f"M = {case['M']}, L = 10: P(R) from T = {start:.3f} to lift-off,\n"
                   f"{fig3_spacing(live, start)}", out)
    last = live[-1]
    s_last = step_of(last, dT)
    fig4 = [t for t in live if t >= last - FIG4_WINDOW - 1e-9 and (s_last - step_of(t, dT)) % FIG4_EVERY_STEPS == 0]
    profile_figure(case, fig4, "fig4", f"M = {case['M']}, L = 10: the last profiles before lift-off, "
                   f"every {FIG4_EVERY_STEPS} steps", out, xlim=(0, 0.6))
    return {"fig3_times": fig3, "fig4_times": fig4}


def rebound_rows(case):
    """spike.csv rows from the maximum deformation to lift-off."""
    s = case["spike"]
    return s["T"] >= case["T_max_deformation"]


def grid_points(case):
    return case["run"]["parameters"]["grid"]["points"]


def note_no_spike(ax, case):
    """Says on an empty plot why it is empty: on a coarse grid no snapshot of the rebound
    has a spike the analysis finds (33^2: none; it needs a finer grid)."""
    n = grid_points(case)
    ax.text(0.5, 0.5, f"M = {case['M']}: no spike found in the rebound on {n}^2 points\n"
            "(too coarse to resolve it: use a finer --grid)",
            transform=ax.transAxes, ha="center", va="center", fontsize=9, color="0.35")


def fig5(cases, dry, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    rows = []
    for case in cases:
        s = case["spike"]
        sel = rebound_rows(case)
        found = np.isfinite(s["R_s"][sel])
        # A curve of a point or two is no line: markers show it.
        ax.plot(s["T"][sel], s["R_s"][sel], lw=1.2, marker="o" if found.sum() < 3 else None,
                ms=3, label=f"M = {case['M']}" + ("" if found.any() else " (no spike found)"))
        rows += [(case["M"], float(t), float(r), float(x), float(a))
                 for t, r, x, a in zip(s["T"][sel], s["R_s"][sel], s["X_s"][sel], s["A_dry"][sel])]
    ax.plot(dry["T"], dry["A_dry"], "k--", lw=1.0, label="dry Hertz A(T)")
    ax.set_xlabel("T")
    ax.set_ylabel("spike position R_s")
    ax.set_xlim(2.0, 4.5)
    ax.set_ylim(0, 1.1)
    ax.set_title("Spike position, L = 10 (dry contact: same start, no shift)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig5.png"), dpi=DPI)
    plt.close(fig)
    write_csv(os.path.join(out, "fig5.csv"), ["M", "T", "R_s", "X_s", "A_dry"], rows)
    write_csv(os.path.join(out, "fig5_dry.csv"), ["T", "A_dry"],
              [(float(t), float(a)) for t, a in zip(dry["T"], dry["A_dry"])])


def fig6(case, out):
    s = case["spike"]
    sel = rebound_rows(case)
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(s["T"][sel], s["V_s"][sel], "-o", ms=2.5, lw=1.0)
    ax.axhline(0, color="0.6", lw=0.6)
    if not np.isfinite(s["V_s"][sel]).any():
        note_no_spike(ax, case)
    ax.set_xlabel("T")
    ax.set_ylabel("V_s = dR_s/dT")
    ax.set_title(f"Spike velocity, M = {case['M']}, L = 10 (finite differences, no filtering)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig6.png"), dpi=DPI)
    plt.close(fig)
    write_csv(os.path.join(out, "fig6.csv"), ["T", "R_s", "V_s"],
              [(float(t), float(r), float(v)) for t, r, v in zip(s["T"][sel], s["R_s"][sel], s["V_s"][sel])])


def histories(cases, dry, out):
    fig, axes = plt.subplots(3, 1, figsize=(6.4, 8.0), sharex=True)
    rows = []
    for case in cases:
        ts = case["ts"]
        label = f"M = {case['M']}"
        axes[0].plot(ts["T"], ts["h_center"], lw=1.0, label=label)
        axes[1].plot(ts["T"], ts["h_min"], lw=1.0, label=label)
        axes[2].plot(ts["T"], ts["force"], lw=1.0, label=label)
        rows += [(case["M"], float(t), float(hc), float(hm), float(f), float(d))
                 for t, hc, hm, f, d in zip(ts["T"], ts["h_center"], ts["h_min"], ts["force"], ts["Delta"])]
    # Dry Hertz force (2 pi / 3) A^3 in the same unit as the film force Int Int P.
    axes[2].plot(dry["T"], 2.0 * math.pi / 3.0 * dry["A_dry"] ** 3, "k--", lw=1.0, label="dry Hertz")
    axes[0].set_ylabel("H at the centre")
    axes[1].set_ylabel("minimum H")
    axes[2].set_ylabel("force Int Int P dX dY")
    axes[2].set_xlabel("T")
    for ax in axes:
        ax.legend(fontsize=7)
    axes[0].set_yscale("log")
    axes[1].set_yscale("log")
    fig.suptitle("Film thickness and force, L = 10")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "histories.png"), dpi=DPI)
    plt.close(fig)
    write_csv(os.path.join(out, "histories.csv"), ["M", "T", "h_center", "h_min", "force", "Delta"], rows)


def load_rolling(study, M):
    """The rolling contact at M (`ehlsim rolling` run by the study), or None if it did not finish."""
    d = os.path.join(study, f"rolling_M{M}")
    if not os.path.exists(os.path.join(d, "run.json")):
        return None
    return {"run": json.load(open(os.path.join(d, "run.json"))),
            "profile": read_csv(os.path.join(d, "profile_x.csv"))}


def similarity(by_M, study, out):
    """The paper's section 2: the impact's central film h_c(T), its time shifted so that the
    largest force is at 0, beside the rolling film H(X, Y = 0) at the same M and L (so the same
    lambda_bar), on common axes.  Returns the figures quoted in docs/validation.md."""
    pairs = [(M, by_M[M], load_rolling(study, M)) for M in SIMILARITY_CASES if M in by_M]
    pairs = [(M, impact, rolling) for M, impact, rolling in pairs if rolling is not None]
    if not pairs:
        return {}
    fig, axes = plt.subplots(1, len(pairs), figsize=(5.5 * len(pairs), 4.2), squeeze=False)
    rows, result = [], {}
    for ax, (M, impact, rolling) in zip(axes[0], pairs):
        ts, profile = impact["ts"], rolling["profile"]
        T_peak = impact["run"]["results"]["T_max_force"]
        shifted = ts["T"] - T_peak
        n_roll = rolling["run"]["parameters"]["grid"]["points"]
        n_imp = impact["run"]["parameters"]["grid"]["points"]
        ax.plot(profile["X"], profile["H"], "-", label=f"rolling: H(X, Y = 0), {n_roll}$^2$")
        ax.plot(shifted, ts["h_center"], "--",
                label=f"impact: $h_c$(T $-$ {T_peak:.2f}), {n_imp}$^2$")
        ax.set_xlim(*SIMILARITY_X_RANGE)
        ax.set_ylim(0, SIMILARITY_H_MAX)
        ax.set_xlabel("X (rolling)  |  T $-$ T(max force) (impact)")
        ax.set_ylabel("H")
        ax.set_title(f"M = {M}, L = 10 (the same $\\bar\\lambda$)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        rows += [(M, "rolling", float(x), float(h)) for x, h in zip(profile["X"], profile["H"])]
        rows += [(M, "impact", float(t), float(h)) for t, h in zip(shifted, ts["h_center"])]
        r = rolling["run"]["results"]
        k = int(np.argmin(np.abs(ts["T"] - T_peak)))
        result[str(M)] = {"rolling_Hc": r["Hc"], "rolling_Hm": r["Hm"], "rolling_X_Hm": r["X_Hm"],
                          "impact_T_max_force": T_peak,
                          "impact_h_center_at_max_force": float(ts["h_center"][k]),
                          "impact_min_h_center": float(np.nanmin(ts["h_center"]))}
    fig.tight_layout()
    fig.savefig(os.path.join(out, "similarity.png"), dpi=DPI)
    plt.close(fig)
    write_csv(os.path.join(out, "similarity.csv"), ["M", "mode", "X_or_T_shifted", "H"], rows)
    return {"similarity": result}


def mean_finite(values):
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.mean(v)) if v.size else float("nan")


def summary(cases, dry):
    out = {"cases": []}
    for case in cases:
        s = case["spike"]
        T, R, V, A = s["T"], s["R_s"], s["V_s"], s["A_dry"]
        sel = rebound_rows(case) & np.isfinite(R)
        entry = {"M": case["M"], "T_lift_off": case["T_lift_off"], "T_diverged": case["T_diverged"],
                 "rebound_speed": case["run"]["results"]["rebound_speed"],
                 "T_max_deformation": case["T_max_deformation"],
                 "steps": case["run"]["results"]["steps"],
                 "unconverged_steps": case["run"]["results"]["unconverged_steps"]}
        if sel.any():
            first, last = np.flatnonzero(sel)[0], np.flatnonzero(sel)[-1]
            entry["spike_first"] = {"T": float(T[first]), "R_s": float(R[first])}
            entry["spike_last"] = {"T": float(T[last]), "R_s": float(R[last])}
            early = sel & (np.abs(T - PAPER_MAX_DEFORMATION_T) <= EARLY_WINDOW + 1e-9)
            own = sel & (T <= case["T_max_deformation"] + 2 * EARLY_WINDOW + 1e-9)
            entry["V_s_after_max_deformation"] = mean_finite(V[own])
            late_idx = np.flatnonzero(sel & np.isfinite(V))[-LATE_STEPS:]
            v_early = mean_finite(V[early])
            v_late = mean_finite(V[late_idx])
            entry["V_s_near_T3"] = v_early
            entry["V_s_before_lift_off"] = v_late
            entry["V_s_before_lift_off_T"] = [float(t) for t in T[late_idx]]
            entry["V_s_ratio"] = v_late / v_early if v_early else float("nan")
            entry["R_s_vs_A_dry"] = []
            for t in COMPARISON_TIMES:
                k = int(np.argmin(np.abs(T - t)))
                entry["R_s_vs_A_dry"].append({"T": float(T[k]), "R_s": float(R[k]), "X_s": float(s["X_s"][k]),
                                              "A_dry": float(A[k]),
                                              "ratio": float(R[k] / A[k]) if A[k] > 0 else float("nan")})
            # Inward motion: the fraction of rebound steps where R_s does not grow.
            r = R[sel]
            entry["inward_fraction"] = float(np.mean(np.diff(r) <= 0)) if r.size > 1 else float("nan")
        out["cases"].append(entry)
    return out


def strict_json(value):
    """`value` with every NaN and infinity as None (null): bare NaN is no JSON."""
    if isinstance(value, dict):
        return {k: strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit("usage: /usr/bin/python3 scripts/plot_study.py STUDY_DIR [FIGURES_DIR]")
    study = sys.argv[1]
    # ehlsim study gives a staging directory, which it puts in place as figures/ when done.
    out = sys.argv[2] if len(sys.argv) == 3 else os.path.join(study, "figures")
    os.makedirs(out, exist_ok=True)
    cases = [load_case(study, M) for M in CASES if os.path.exists(os.path.join(study, f"M{M}", "run.json"))]
    if not cases:
        sys.exit(f"no finished cases in {study}")
    by_M = {c["M"]: c for c in cases}
    dry = read_csv(os.path.join(study, "dry.csv"))
    result = {}
    # The figures a finished case could not give (its run ended before their
    # times, e.g. with time.T_end): the script draws the others, then fails.
    missing = []
    if COMPARISON_CASE in by_M:
        fig1 = fig1_fig2(by_M[COMPARISON_CASE], out)
        if fig1 is None:
            missing.append(f"figures 1-2: no snapshot of M = {COMPARISON_CASE} at T >= {COMPARISON_T}")
        result["fig1"] = fig1 or {}
    if PROFILE_CASE in by_M:
        profiles = fig3_fig4(by_M[PROFILE_CASE], out)
        if profiles is None:
            missing.append(f"figures 3-4: no snapshots of M = {PROFILE_CASE} after T = {FIRST_PROFILE_T}")
        result.update(profiles or {})
        fig6(by_M[PROFILE_CASE], out)
    fig5(cases, dry, out)
    histories(cases, dry, out)
    result.update(similarity(by_M, study, out))
    result.update(summary(cases, dry))
    result = strict_json(result)
    with open(os.path.join(out, "summary.json"), "w") as f:
        json.dump(result, f, indent=2, allow_nan=False)
    print(json.dumps(result, indent=2, allow_nan=False))
    if missing:
        sys.exit("; ".join(missing))


if __name__ == "__main__":
    main()
