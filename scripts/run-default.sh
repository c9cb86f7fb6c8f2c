#!/usr/bin/env bash
# One command on a fresh machine: install the dependencies, build, and run the
# embedded default case (M = 100, L = 10, 257^2, until lift-off) into run/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
./build/apps/ehlsim impact --out "${1:-run}"
