#!/usr/bin/env bash
# Builds anchormap and runs every test: the README's test command; .ci/run calls it.
#   0. Every C++ file is clang-formatted.
#   1. Release build (gcc) with warnings as errors, then ctest.
#   2. Sanitizer pass: one clang build (build-asan-fuzz/) with -fsanitize=address,undefined
#      and libFuzzer's coverage instrumentation (-fsanitize=fuzzer-no-link), warnings as
#      errors; ctest runs the same tests there under ASan + UBSan, and the libFuzzer targets
#      of tests/fuzz link from the same objects. Each target then runs once for
#      ANCHORMAP_FUZZ_SECONDS (default 20) from its seed corpus in tests/fuzz/corpus/ (new
#      inputs go to build-asan-fuzz/corpus/, not the repository), as many at once as cores.
#      Without clang or libFuzzer the pass builds with gcc instead (build-asan/), runs the
#      same ctest and says that the fuzz targets were skipped.
# Set ANCHORMAP_SKIP_SANITIZE=1 to run only the first pass while iterating locally, and
# ANCHORMAP_SKIP_FUZZ=1 to leave out the fuzz runs (the sanitizer build and ctest still run).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh

jobs=$(nproc)

# Each phase's wall time and the CPU seconds (user + system) of the processes it ran, so that
# a slow CI run shows where the time went.
# `times` runs in this shell (not in a pipe or $(...), which would fork and count nothing).
times_file=$(mktemp)
trap 'rm -f "$times_file"' EXIT
children_cpu() {
  local _ user sys
  times >"$times_file"
  { read -r _ _; read -r user sys; } <"$times_file"
  cpu=$(awk -v u="$user" -v s="$sys" 'function sec(t, p) { split(t, p, /[ms]/); return p[1] * 60 + p[2] }
    BEGIN { printf "%.1f", sec(u) + sec(s) }')
}
phase_name="" phase_wall=0 phase_cpu=0 cpu=0
phase() {
  phase_end
  children_cpu
  phase_name=$1 phase_wall=$(date +%s.%N) phase_cpu=$cpu
  echo "== $1 ($(date +%H:%M:%S))"
}
phase_end() {
  [ -n "$phase_name" ] || return 0
  children_cpu
  awk -v n="$phase_name" -v w0="$phase_wall" -v w1="$(date +%s.%N)" -v c0="$phase_cpu" -v c1="$cpu" \
    'BEGIN { printf "== time: %s: %.0f s wall, %.0f s CPU (user + system)\n", n, w1 - w0, c1 - c0 }'
  phase_name=""
}

run_pass() {
  local name=$1 dir=$2; shift 2
  phase "$name: build"
  cmake -S . -B "$dir" -DANCHORMAP_WERROR=ON "$@" >/dev/null
  cmake --build "$dir" -j "$jobs"
  phase "$name: ctest"
  (cd "$dir" && ctest --output-on-failure -j "$jobs" --timeout 900 \
    ${ANCHORMAP_CTEST_EXCLUDE:+-E "$ANCHORMAP_CTEST_EXCLUDE"})
  phase_end
}

phase "Formatting (clang-format, .clang-format at the root)"
if ! find common agent server tools tests \( -name '*.cc' -o -name '*.h' \) -print0 |
    xargs -0 clang-format --dry-run -Werror; then
  echo "test.sh: files above are not clang-formatted (fix: clang-format -i FILE)" >&2
  exit 1
fi

run_pass "Release (gcc, warnings are errors)" build -DCMAKE_BUILD_TYPE=Release

# Whether clang can build the fuzz targets: clang, clang++ and libFuzzer's runtime.
clang_fuzz_missing() {
  if ! command -v clang++ >/dev/null || ! command -v clang >/dev/null; then
    echo "clang/clang++ not found (Debian: apt-get install clang)"
    return 0
  fi
  local probe
  probe=$(mktemp -d)
  if ! echo 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }' |
      clang++ -x c++ -fsanitize=fuzzer,address,undefined - -o "$probe/probe" 2>/dev/null; then
    rm -rf "$probe"
    echo "clang++ cannot link -fsanitize=fuzzer (libclang_rt.fuzzer missing)"
    return 0
  fi
  rm -rf "$probe"
  return 1
}

fuzz_run() {
  local tree=$1 seconds=${ANCHORMAP_FUZZ_SECONDS:-20}
  phase "Fuzz targets: -fsanitize=fuzzer,address,undefined, ${seconds} s per target"
  # Targets are single-threaded: run as many at once as there are cores.
  mkdir -p "$tree/artifacts"
  rm -f "$tree"/fuzz-*.rc
  local dir target failed=""
  for dir in tests/fuzz/corpus/*/; do
    target=$(basename "$dir")
    mkdir -p "$tree/corpus/$target"
    while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
    (
      rc=0
      "$tree/fuzz/fuzz-$target" -max_total_time="$seconds" -timeout=20 \
        -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$tree/artifacts/$target-" \
        "$tree/corpus/$target" "$dir" >"$tree/fuzz-$target.log" 2>&1 || rc=$?
      echo $rc >"$tree/fuzz-$target.rc"
    ) &
  done
  wait
  for dir in tests/fuzz/corpus/*/; do
    target=$(basename "$dir")
    echo "-- fuzz-$target: $(grep -E '^Done ' "$tree/fuzz-$target.log" || echo 'no summary')"
    if [ "$(cat "$tree/fuzz-$target.rc" 2>/dev/null)" != 0 ]; then
      tail -n 60 "$tree/fuzz-$target.log" >&2
      echo "test.sh: fuzz-$target found a bug (log: $tree/fuzz-$target.log)" >&2
      failed="$failed $target"
    fi
  done
  phase_end
  [ -z "$failed" ] || exit 1
}

if [ "${ANCHORMAP_SKIP_SANITIZE:-0}" != "1" ]; then
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  # Run in the Release pass only (CI's time): the two longest data tests (city10000 against
  # batch, the per-update oracle in iSAM's mode: 3.5 of the pass's minutes under ASan), whose
  # smaller siblings (M3500, the oracle in the server's mode) cover the same code here, and
  # three determinism tests (same input, same map: 70 s under ASan for two of them; two
  # whole replays for the third) whose code the merge tests (AgentServerTest.ThreeRobots...,
  # ScanEncountersTest.TwoRobots...) run here. Likewise
  # the three longest scan-matching scenarios (122-178 s each in this tree on a loaded
  # machine, 4-12 s in Release): 20 % injected false candidates, a loop across large drift
  # and the 200-trial covariance consistency; the same matcher and source code runs here in
  # the shorter scenarios (two robots joining, the look-alike refusals, loop closing, the
  # matcher's recovery tests). This pays for crash_scan_test in the Release pass. And the
  # solve period's restart (233 s under ASan on a loaded machine, 5 s in Release): its
  # snapshot code runs here in the other SnapshotCodecTest restarts. And two scenario tests of
  # 18-25 s in Release that took 155-191 s each under ASan (CI's margin): the wide search that
  # does not pause (four loop runs; ClosingTheLoop... and the look-alike refusals run the same
  # loop closure code here) and the restart with the scan sources (the other SnapshotCodecTest
  # restarts and ScanJournalTest's restart run that code here).
  export ANCHORMAP_CTEST_EXCLUDE='IncrementalVsBatchTest\.City10000|PerUpdateOracleTest\.IsamMode|AgentServerTest\.OfflineServerOnARecordedLogIsDeterministicAndAgrees|ScanEncountersTest\.SameInputSameMap|ReplayDeterminismTest\.|ScanEncountersTest\.FalseCandidatesDoNotCorruptTheMap|LoopClosuresTest\.WideSearchClosesALoopAcrossLargeDrift|CorrelativeMatcherTest\.CovarianceIsConsistent|SnapshotCodecTest\.WithASolvePeriodARestoredServerContinuesExactly|LoopClosuresTest\.AClosureDoesNotPauseTheWideSearch|SnapshotCodecTest\.WithTheScanSourcesOnARestoredServerContinuesExactly'
  if why=$(clang_fuzz_missing); then
    echo "== fuzz targets SKIPPED: $why"
    run_pass "ASan + UBSan (gcc)" build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DANCHORMAP_SANITIZE=ON
  else
    CC=clang CXX=clang++ run_pass "ASan + UBSan (clang, with the libFuzzer targets)" build-asan-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DANCHORMAP_SANITIZE=ON -DANCHORMAP_FUZZ=ON
    if [ "${ANCHORMAP_SKIP_FUZZ:-0}" != "1" ]; then
      unset ASAN_OPTIONS UBSAN_OPTIONS
      fuzz_run build-asan-fuzz
    fi
  fi
fi
echo "== all tests passed"
