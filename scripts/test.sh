#!/usr/bin/env bash
# One command on a fresh machine: install the dependencies, build, and run the
# whole test suite (ctest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j 2
