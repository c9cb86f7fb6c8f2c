#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) into build-fuzz/ (or
# $EHLSIM_FUZZ_DIR) and fuzzes each, starting from its committed corpus, for
# $EHLSIM_FUZZ_SECONDS seconds (default 20): what .ci/run does.
#
# The fuzzers run in libFuzzer's fork mode, which goes on after a crash: HDF5
# 1.10.8 itself crashes or hangs on some damaged files (docs/validation.md,
# "Fuzzing and sanitizers").  Each crashing input is then run again alone and
# its stack read: a crash, sanitizer report, uncaught exception, timeout or
# out-of-memory whose first frame outside the sanitizer, libc and libstdc++ is
# in ehlsim fails the script; one inside libhdf5/libnetcdf is counted and
# listed as the library's.  The inputs stay in $EHLSIM_FUZZ_DIR/artifacts/.
set -euo pipefail
cd "$(dirname "$0")/.."
FUZZ_DIR=${EHLSIM_FUZZ_DIR:-build-fuzz}
SECONDS_EACH=${EHLSIM_FUZZ_SECONDS:-20}
CC=clang CXX=clang++ cmake -S . -B "$FUZZ_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DEHLSIM_BUILD_FUZZERS=ON -DEHLSIM_BUILD_TESTS=OFF -DEHLSIM_BUILD_BENCH=OFF >/dev/null
TARGETS=(fuzz_config fuzz_checkpoint fuzz_fields)
cmake --build "$FUZZ_DIR" -j "$(nproc)" --target "${TARGETS[@]}"

# The largest input of each target: its biggest seed, with room to grow.  A
# seed longer than that would be cut by libFuzzer (a truncated HDF5 file that
# nc_open refuses at once): the loop below refuses to run then.
declare -A MAX_LEN=([fuzz_config]=4096 [fuzz_checkpoint]=20480 [fuzz_fields]=34000)
declare -A EXTRA=([fuzz_config]="-dict=fuzz/config.dict")
export LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
LIMITS=(-timeout=10 -rss_limit_mb=2048 -detect_leaks=0)

# "library" when the first frame of the report outside the sanitizers, libc,
# libstdc++ and libFuzzer is in libhdf5 or libnetcdf, else "ehlsim".
culprit() {
  grep -E '^ +#[0-9]+ 0x' "$1" |
    grep -vE '__sanitizer|__asan|__ubsan|__lsan|__interceptor|fuzzer::|libc\.so|libstdc\+\+|nptl/|signal/|stdlib/|in (malloc|calloc|realloc|memcpy|memmove|strdup) ' |
    head -n 1 | grep -qE 'libhdf5|libnetcdf' && echo library || echo ehlsim
}

status=0
for target in "${TARGETS[@]}"; do
  name=${target#fuzz_}
  work="$FUZZ_DIR/corpus/$name"  # new inputs go here, not into the tree
  artifacts="$FUZZ_DIR/artifacts/$name"
  largest=$(find "tests/fuzz-corpus/$name" -type f -printf '%s\n' | sort -n | tail -n 1)
  if [ "${largest:-0}" -gt "${MAX_LEN[$target]}" ]; then
    echo "fuzz: $target: a seed of $largest bytes is longer than -max_len=${MAX_LEN[$target]}"
    status=1
    continue
  fi
  rm -rf "$artifacts" && mkdir -p "$work" "$artifacts"
  # shellcheck disable=SC2086
  "$FUZZ_DIR/fuzz/$target" -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
    -max_total_time="$SECONDS_EACH" -max_len="${MAX_LEN[$target]}" "${LIMITS[@]}" \
    -artifact_prefix="$artifacts/" ${EXTRA[$target]:-} "$work" "tests/fuzz-corpus/$name" \
    >"$FUZZ_DIR/$target.log" 2>&1 || true
  runs=$(grep -oE '^#[0-9]+' "$FUZZ_DIR/$target.log" | tail -n 1 | tr -d '#')
  library=0
  for input in "$artifacts"/*; do
    [ -e "$input" ] || continue
    if "$FUZZ_DIR/fuzz/$target" "${LIMITS[@]}" "$input" >"$input.report" 2>&1; then
      echo "fuzz: $target: $input did not fail when run alone"
    elif [ "$(culprit "$input.report")" = library ]; then
      library=$((library + 1))
    else
      echo "fuzz: $target: ehlsim fails on $input:"
      tail -n 40 "$input.report"
      status=1
    fi
  done
  echo "fuzz: $target: ${runs:-0} executions in ${SECONDS_EACH} s; $library inputs crash inside HDF5/NetCDF"
done
exit $status
