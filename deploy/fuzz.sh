#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Fuzz gearsim with libFuzzer (clang, -fsanitize=fuzzer,address,undefined):
# builds the library instrumented in its own build directory and runs each
# target (tests/fuzz: request = the service's request handling without
# sockets, scene = gs_scene_parse) for --time seconds from the seed corpus
# tests/fuzz/corpus/TARGET. Findings go to BUILD/fuzz-out/TARGET/ (crash-*,
# timeout-*, leak-*); the new inputs the fuzzer keeps go to
# BUILD/fuzz-out/TARGET/corpus. Exit status 1 when a target found something.
#
#   deploy/fuzz.sh                       # 10 minutes per target
#   deploy/fuzz.sh --time 3600 --target scene
#   deploy/fuzz.sh --time 5 --skip-if-missing   # what the test suite runs
#
# Needs the Debian packages clang and libclang-rt-14-dev (deploy/install-deps.sh).
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
time=600
build="$root/build-fuzz"
targets="request scene checkpoint"
skip_missing=0
jobs=1
while [ $# -gt 0 ]; do
  case "$1" in
    --time) time=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --target) targets=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --skip-if-missing) skip_missing=1; shift ;;
    -h|--help) sed -n '3,17p' "$0"; exit 0 ;;
    *) echo "fuzz.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
[ "$targets" = all ] && targets="request scene checkpoint"

# Is libFuzzer there? (clang alone is not enough: the runtime is libclang-rt-*-dev.)
probe=$(mktemp -d)
trap 'rm -rf "$probe"' EXIT
echo 'int LLVMFuzzerTestOneInput(const unsigned char *d, unsigned long n) { (void)d; (void)n; return 0; }' >"$probe/p.c"
if ! command -v clang >/dev/null || ! clang -fsanitize=fuzzer,address,undefined "$probe/p.c" -o "$probe/p" 2>/dev/null; then
  echo "fuzz.sh: clang with libFuzzer is not installed (apt-get install clang libclang-rt-14-dev)"
  [ $skip_missing = 1 ] && exit 77
  exit 2
fi

. "$root/deploy/env.sh"
if [ ! -f "$build/build.ninja" ]; then
  CC=clang meson setup "$build" "$root" --buildtype=debugoptimized \
    -Db_sanitize=address,undefined -Db_lundef=false \
    "-Dc_args=-fsanitize=fuzzer-no-link -fno-sanitize-recover=undefined -fno-omit-frame-pointer" \
    "-Dc_link_args=-fno-sanitize-recover=undefined" >"$probe/setup.log" 2>&1 \
    || { cat "$probe/setup.log"; echo "fuzz.sh: meson setup failed"; exit 1; }
fi
ninja -C "$build" $(for t in $targets; do echo "tests/fuzz/fuzz_$t"; done) >"$probe/ninja.log" 2>&1 \
  || { tail -40 "$probe/ninja.log"; echo "fuzz.sh: build failed"; exit 1; }

export ASAN_OPTIONS="${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$root/tests/fuzz/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
status=0
for t in $targets; do
  out="$build/fuzz-out/$t"
  mkdir -p "$out/corpus"
  log="$out/fuzz.log"
  echo "== fuzz_$t: ${time}s from $root/tests/fuzz/corpus/$t (log $log)"
  # The request target starts a singleton MPI runtime whose helper threads
  # allocate behind the fuzzer's back: its leak reports are false positives
  # (the scene target keeps leak detection).
  leaks=1
  asan=$ASAN_OPTIONS
  if [ "$t" = request ] || [ "$t" = checkpoint ]; then leaks=0; asan="$ASAN_OPTIONS:detect_leaks=0"; fi
  (cd "$out" && ASAN_OPTIONS=$asan "$build/tests/fuzz/fuzz_$t" -detect_leaks=$leaks \
     -max_total_time="$time" -timeout=30 -rss_limit_mb=4096 \
     -max_len=65536 -print_final_stats=1 $([ "$jobs" -gt 1 ] && echo "-jobs=$jobs -workers=$jobs") \
     -artifact_prefix="$out/" "$out/corpus" "$root/tests/fuzz/corpus/$t") >"$log" 2>&1
  rc=$?
  [ "$jobs" -gt 1 ] && cat "$out"/fuzz-*.log >>"$log" 2>/dev/null
  execs=$(grep -h 'stat::number_of_executed_units' "$log" | awk '{s += $2} END {print s + 0}')
  cov=$(grep -hE '^#[0-9]+.*(DONE|pulse|NEW|REDUCE)' "$log" | tail -1 | grep -oE 'cov: [0-9]+ ft: [0-9]+')
  found=$(ls "$out" | grep -cE '^(crash|leak|timeout|oom|slow-unit)-' || true)
  echo "fuzz_$t: exit $rc, $execs executions, ${cov:-cov ?}, corpus $(ls "$out/corpus" | wc -l) files, $found finding(s)"
  if [ $rc -ne 0 ] || [ "$found" -gt 0 ]; then
    status=1
    grep -hE 'ERROR: |SUMMARY: |runtime error|==ERROR|Test unit written' "$log" | head -20
  fi
done
exit $status
