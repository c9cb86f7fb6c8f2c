#!/usr/bin/env bash
# One command on a fresh machine: install the dependencies, build, and run the
# embedded default case (M = 100, L = 10, 257^2, until lift-off) into run/.
# A DIR given is taken from where the script was called, the default run/
# in the repository.
set -euo pipefail
out="${1:-}"
if [[ -n "$out" && "$out" != /* ]]; then out="$PWD/$out"; fi
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
./build/apps/ehlsim impact --out "${out:-run}"
