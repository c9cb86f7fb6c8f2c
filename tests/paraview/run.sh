#!/usr/bin/env bash
# ctest's entry to open_fields.py: ParaView's pvbatch on a virtual X display.
# Skipped (exit 77, ctest's SKIP_RETURN_CODE) only when pvbatch is missing.
set -euo pipefail
if ! command -v pvbatch >/dev/null; then
  echo "SKIPPED: pvbatch not found (Debian packages paraview and python3-paraview, scripts/setup.sh)"
  exit 77
fi
# A 24-bit screen: on xvfb-run's default 8-bit one, ParaView's OpenGL context fails (GLXBadContext).
exec xvfb-run -a -s "-screen 0 1280x1024x24" pvbatch "$(dirname "$0")/open_fields.py" "$@"
