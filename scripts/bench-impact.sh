#!/usr/bin/env bash
# End-to-end benchmark of `ehlsim impact` (the default case M = 100, L = 10 on
# several grids).  Prints a markdown table: grid, steps, wall time, time per
# step, mean multigrid cycles per step, lift-off time, rebound speed, steps
# that ended unconverged (at solver.max_cycles), steps that were solved again
# with more damping (when run.json reports them), and the load average before
# each run.  A run that fails (exit 1) is reported with the step it failed at.
#
#   bash scripts/bench-impact.sh                    129^2, 257^2 to lift-off; 513^2 to T = 1.5
#   bash scripts/bench-impact.sh --lift-off-513     513^2 to lift-off as well (long)
#   bash scripts/bench-impact.sh --grids "65 129"   other grids (all < 513 run to lift-off)
#   bash scripts/bench-impact.sh -- --set solver.switch_ratio=0.3   extra arguments for every run
#
# Options:
#   --grids "N ..."   grid points per side (default "129 257 513")
#   --lift-off-513    run grids of 513 points and more to lift-off too (default: to --t-end)
#   --t-end T         end time of the grids of 513 points and more (default 1.5)
#   --keep DIR        keep the run directories under DIR (default: a temporary directory, removed)
#   -h, --help        this text
# Environment:
#   EHLSIM            the binary (default: build/apps/ehlsim of this checkout; scripts/build.sh).
#                     It is copied once at the start, so a rebuild during the benchmark
#                     cannot mix two versions.
#   EHLSIM_REVISION   label for the source revision of that binary (default: this
#                     checkout's HEAD when EHLSIM is not set)
#   OMP_NUM_THREADS, OMP_WAIT_POLICY   passed through to ehlsim (and printed).
#
# Wall time is that of the whole process (set-up, FFTW planning, output
# included); time per step is wall time / steps; CPU is the user + system time
# of the process (all threads).  The numbers depend on what else runs on the
# machine: the load average is printed with them.  On a busy machine, OpenMP
# threads that spin while waiting inflate both wall and CPU time; compare with
# OMP_WAIT_POLICY=passive (docs/performance.md).
set -euo pipefail
# Paths the caller gives (EHLSIM, --keep, files among the extra arguments) are
# the caller's: the script does not change directory.
REPO=$(cd "$(dirname "$0")/.." && pwd)

PYTHON=/usr/bin/python3  # Debian's python3 (json, csv from the standard library)
GRIDS="129 257 513"
LIFT_OFF_LARGE=0
T_END_LARGE=1.5
KEEP=""
EXTRA=()

usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }

while [ $# -gt 0 ]; do
  case "$1" in
    --grids) GRIDS=$2; shift 2 ;;
    --lift-off-513) LIFT_OFF_LARGE=1; shift ;;
    --t-end) T_END_LARGE=$2; shift 2 ;;
    --keep) KEEP=$2; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    --) shift; EXTRA=("$@"); break ;;
    *) echo "bench-impact: unknown option '$1' (try --help)" >&2; exit 2 ;;
  esac
done

EHLSIM_SET=${EHLSIM:-}
EHLSIM=${EHLSIM:-$REPO/build/apps/ehlsim}
if [ ! -x "$EHLSIM" ]; then
  echo "bench-impact: no ehlsim binary at '$EHLSIM' (run: bash scripts/build.sh)" >&2
  exit 2
fi
if [ ! -x "$PYTHON" ]; then
  echo "bench-impact: $PYTHON not found (Debian: apt-get install python3)" >&2
  exit 2
fi

WORK=$(mktemp -d "${TMPDIR:-/tmp}/ehlsim-bench.XXXXXX")
if [ -z "$KEEP" ]; then
  trap 'rm -rf "$WORK"' EXIT
  RUNS=$WORK
else
  mkdir -p "$KEEP"
  RUNS=$KEEP
fi
cp "$EHLSIM" "$WORK/ehlsim"
BIN=$WORK/ehlsim

cpu_model=$(lscpu 2>/dev/null | sed -n 's/^Model name:[[:space:]]*//p' | head -n 1)
[ -n "$cpu_model" ] || cpu_model=$(sed -n 's/^model name[[:space:]]*:[[:space:]]*//p' /proc/cpuinfo | head -n 1)
revision=$(git -C "$REPO" rev-parse --short HEAD 2>/dev/null || echo unknown)
if [ -n "$(git -C "$REPO" status --porcelain --untracked-files=no -- src apps CMakeLists.txt 2>/dev/null)" ]; then
  revision="$revision + uncommitted changes in src/ or apps/"
fi
if [ -n "${EHLSIM_REVISION:-}" ]; then
  revision=$EHLSIM_REVISION
elif [ -n "$EHLSIM_SET" ]; then
  revision="not known (binary given by EHLSIM; this checkout is at $revision)"
fi

echo "# ehlsim impact benchmark"
echo
echo "- date: $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "- binary: $EHLSIM ($("$BIN" --version)), source revision: $revision"
echo "- CPU: ${cpu_model:-unknown}; nproc: $(nproc)"
echo "- OMP_NUM_THREADS=${OMP_NUM_THREADS:-unset}, OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-unset}"
echo "- load average at start: $(cut -d ' ' -f 1-3 /proc/loadavg)"
[ ${#EXTRA[@]} -eq 0 ] || echo "- extra arguments: ${EXTRA[*]}"
echo

# CPU time (user + system) of all finished children of this shell, in seconds,
# into CPU.  Not to be called in $(...): `times` in a subshell sees no children.
child_cpu() {
  times >"$WORK/times"
  CPU=$(awk 'NR == 2 { s = 0; for (k = 1; k <= NF; k++) { split($k, b, "m"); sub("s", "", b[2]); s += b[1] * 60 + b[2] } printf "%.2f", s }' "$WORK/times")
}

ROWS=$WORK/rows.jsonl
: >"$ROWS"
for n in $GRIDS; do
  args=(impact --quiet --set "grid.points=$n")
  if [ "$n" -ge 513 ] && [ "$LIFT_OFF_LARGE" -eq 0 ]; then
    args+=(--set "time.T_end=$T_END_LARGE")
    goal="to T = $T_END_LARGE"
  else
    goal="to lift-off"
  fi
  out=$RUNS/run-$n
  rm -rf "$out"
  args+=(--out "$out" "${EXTRA[@]}")
  load=$(cut -d ' ' -f 1 /proc/loadavg)
  echo "bench-impact: ${n}^2 $goal (load $load) ..." >&2
  child_cpu
  cpu0=$CPU
  start=$(date +%s.%N)
  rc=0
  "$BIN" "${args[@]}" 2>"$WORK/stderr-$n" || rc=$?
  end=$(date +%s.%N)
  child_cpu
  cpu1=$CPU
  "$PYTHON" - "$out" "$n" "$start" "$end" "$rc" "$load" "$WORK/stderr-$n" "$cpu0" "$cpu1" >>"$ROWS" <<'EOF'
import csv, json, os, re, sys
out, n, start, end, rc, load, err, cpu0, cpu1 = sys.argv[1:]
row = {"grid": int(n), "wall": float(end) - float(start), "rc": int(rc), "load": load,
       "cpu": float(cpu1) - float(cpu0)}
if row["rc"] != 0 or not os.path.exists(os.path.join(out, "run.json")):
    with open(err) as f:
        lines = [l.strip() for l in f if l.strip()]
    row["error"] = lines[-1] if lines else "exit code %s" % rc
    # A diverged step names itself: "time step 354 (T = 4.14844): ...".
    m = re.search(r"time step (\d+) \(T = ([0-9.eE+-]+)\)", row["error"])
    if m:
        row["failed_step"], row["failed_T"] = int(m.group(1)), float(m.group(2))
else:
    with open(os.path.join(out, "run.json")) as f:
        run = json.load(f)
    tol = run["parameters"]["solver"]["tolerance"]
    with open(os.path.join(out, "timeseries.csv"), newline="") as f:
        steps = list(csv.DictReader(f))
    res = run["results"]
    row.update(
        steps=res["steps"],
        cycles=sum(int(s["cycles"]) for s in steps) / max(len(steps), 1),
        max_cycles=max((int(s["cycles"]) for s in steps), default=0),
        unconverged=sum(1 for s in steps if float(s["residual"]) >= tol),
        retried=res.get("retried_steps"),  # steps solved again with more damping (if reported)
        lifted_off=res["lifted_off"],
        T_lift_off=res["T_lift_off"],
        T_final=res["T_final"],
        rebound=res["rebound_speed"],
        solver_wall=run["solver_wall_seconds"],
    )
print(json.dumps(row))
EOF
  echo "bench-impact: ${n}^2 done in $(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.1f", b - a }') s (exit $rc)" >&2
done

"$PYTHON" - "$ROWS" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
failures = []
print("| grid | steps | wall [s] | CPU [s] | time/step [s] | cycles/step (max) | lift-off T | rebound speed | unconverged steps | retried steps | load 1 min |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    g = "%d^2" % r["grid"]
    if "error" in r:
        if "failed_step" in r:  # the steps before the failed one were done
            done = r["failed_step"] - 1
            print("| %s | %d, then failed | %.1f | %.1f | %.3f | | failed at T = %.4f (exit %d) | | | | %s |" % (
                g, done, r["wall"], r["cpu"], r["wall"] / max(done, 1), r["failed_T"], r["rc"], r["load"]))
        else:
            print("| %s | failed | %.1f | %.1f | | | | | | | %s |" % (g, r["wall"], r["cpu"], r["load"]))
        failures.append("%s: %s" % (g, r["error"]))
        continue
    lift = "%.4f" % r["T_lift_off"] if r["lifted_off"] else "none by T = %.4g" % r["T_final"]
    reb = "%.4f" % r["rebound"] if r["lifted_off"] else "-"
    retried = "-" if r.get("retried") is None else "%d" % r["retried"]
    print("| %s | %d | %.1f | %.1f | %.3f | %.2f (%d) | %s | %s | %d | %s | %s |" % (
        g, r["steps"], r["wall"], r["cpu"], r["wall"] / max(r["steps"], 1), r["cycles"],
        r["max_cycles"], lift, reb, r["unconverged"], retried, r["load"]))
if failures:
    print()
    for f in failures:
        print("- " + f)
EOF
echo
echo "load average at end: $(cut -d ' ' -f 1-3 /proc/loadavg)"
[ -z "$KEEP" ] || echo "run directories kept in $KEEP"
