#!/usr/bin/env bash
# ctest's entry to open_fields.py: ParaView's pvbatch on a virtual X display
# (xvfb-run).  Skipped (exit 77, ctest's SKIP_RETURN_CODE) only when pvbatch is
# missing.
set -euo pipefail
if ! command -v pvbatch >/dev/null; then
  echo "SKIPPED: pvbatch not found (Debian packages paraview and python3-paraview, scripts/setup.sh)"
  exit 77
fi
# On the development VM, Xvfb drops about one connection in ten during the X
# handshake (measured: 6 to 65 failed xcb_connect of 300), and pvbatch then
# aborts with "bad X server connection".  Only that failure is tried again.
# With both cores busy it is far more: 6 of 15 starts failed (2026-11-26),
# and a CI rehearsal lost all of 3 attempts; 8 attempts fail together about
# once in 1500 at that rate.
readonly ATTEMPTS=8
script="$(dirname "$0")/open_fields.py"
for attempt in $(seq "$ATTEMPTS"); do
  status=0
  output=$(xvfb-run -a pvbatch "$script" "$@" 2>&1) || status=$?
  printf '%s\n' "$output"
  if [ "$status" -eq 0 ] || ! grep -q "bad X server connection" <<<"$output"; then
    exit "$status"
  fi
  echo "pvbatch could not connect to the virtual X display (attempt $attempt of $ATTEMPTS)"
  sleep 1
done
exit "$status"
