#!/usr/bin/env bash
# Two ehlsim runs started together against one run alone (the machine shared
# with a second job): prints the wall and CPU time of each, and each shared
# run's time over the solo time.  The issue's target is at most 2.2.
#
#   bash scripts/bench-concurrent.sh [extra ehlsim arguments, e.g. --set grid.points=129]
#
# EHLSIM selects the binary (default: build/apps/ehlsim of this checkout).  OMP_NUM_THREADS is
# passed through; unset, each run chooses its own team (docs/usage.md, Threads).
set -euo pipefail
# The caller's paths (EHLSIM, files among the arguments) stay the caller's.
REPO=$(cd "$(dirname "$0")/.." && pwd)
EHLSIM=${EHLSIM:-$REPO/build/apps/ehlsim}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

timed() {  # timed LABEL DIR ARGS...: runs ehlsim, writes "LABEL wall user" to DIR.time
  local label=$1 dir=$2
  shift 2
  /usr/bin/time -f "$label %e %U" -o "$dir.time" "$EHLSIM" impact --quiet --out "$dir" "$@"
}

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
timed solo "$WORK/solo" "$@"
timed shared-1 "$WORK/a" "$@" &
timed shared-2 "$WORK/b" "$@" &
wait
solo=$(cut -d' ' -f2 "$WORK/solo.time")
echo "| run | wall [s] | CPU [s] | wall / solo wall |"
echo "|---|---|---|---|"
for f in "$WORK/solo.time" "$WORK/a.time" "$WORK/b.time"; do
  read -r label wall user <"$f"
  echo "| $label | $wall | $user | $(awk -v a="$wall" -v b="$solo" 'BEGIN { printf "%.2f", a / b }') |"
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
