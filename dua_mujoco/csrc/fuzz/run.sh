#!/usr/bin/env bash
# Builds and runs the tables fuzzer (docs/hardening.md):
#
#   dua_mujoco/csrc/fuzz/run.sh [SECONDS] [libFuzzer options...]
#
# SECONDS (default 60) of fuzzing from the seeds (tests/fuzz/make_seeds.py) and the corpus kept
# under $DUA_FUZZ_DIR (default build/fuzz); any finding is written there as crash-*, leak-*, oom-*
# or timeout-* and fails the run. Needs clang++-14 (or $CXX) with libFuzzer, and the package
# installed in the running Python (pip install -e .).
set -euo pipefail
root="$(cd "$(dirname "$0")/../../.." && pwd)"
seconds="${1:-60}"
shift || true
out="${DUA_FUZZ_DIR:-$root/build/fuzz}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
cxx="${CXX:-clang++-14}"

python "$root/tests/fuzz/make_seeds.py" "$out"
cmake -S "$root/dua_mujoco/csrc" -B "$out/cmake" -DDUA_FUZZ=ON -DCMAKE_CXX_COMPILER="$cxx" \
  -DPython_EXECUTABLE="$(command -v python)" >"$out/cmake.log"
cmake --build "$out/cmake" -j "$(nproc)" >>"$out/cmake.log"
mkdir -p "$out/corpus" "$out/findings"
# -rss_limit_mb: a case must not need 2 GB (a table that sizes a buffer from a count it holds).
set +e
DUA_FUZZ_DIR="$out" "$out/cmake/tables_fuzzer" "$out/corpus" "$out/seeds" \
  -max_total_time="$seconds" -max_len=262144 -rss_limit_mb=2048 -timeout=60 \
  -artifact_prefix="$out/findings/" -print_final_stats=1 "$@" >"$out/fuzz.log" 2>&1
status=$?
set -e
# The cases run: libFuzzer's final stats, or in fork mode (-fork=N) its last progress line.
grep -E "^(Done|stat::number_of_executed_units|stat::average_exec_per_sec|SUMMARY|tables_fuzzer:)" \
  "$out/fuzz.log" || true
grep -E "^#[0-9]+: cov" "$out/fuzz.log" | tail -n 1 || true
if compgen -G "$out/findings/*" >/dev/null; then
  echo "tables fuzzer findings in $out/findings (the log: $out/fuzz.log; reproduce one with"
  echo "DUA_FUZZ_DIR=$out $out/cmake/tables_fuzzer FILE):"
  ls "$out/findings"
  exit 1
fi
if [ "$status" -ne 0 ]; then
  echo "the tables fuzzer exited with status $status: $out/fuzz.log"
  exit "$status"
fi
