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
run_pass() {
  local dir=$1; shift
  cmake -S . -B "$dir" -DANCHORMAP_WERROR=ON "$@" >/dev/null
  cmake --build "$dir" -j "$jobs"
  (cd "$dir" && ctest --output-on-failure -j "$jobs" --timeout 900 \
    ${ANCHORMAP_CTEST_EXCLUDE:+-E "$ANCHORMAP_CTEST_EXCLUDE"})
}

echo "== Formatting (clang-format, .clang-format at the root)"
if ! find common agent server tools tests \( -name '*.cc' -o -name '*.h' \) -print0 |
    xargs -0 clang-format --dry-run -Werror; then
  echo "test.sh: files above are not clang-formatted (fix: clang-format -i FILE)" >&2
  exit 1
fi

echo "== Release build (warnings are errors) and tests"
run_pass build -DCMAKE_BUILD_TYPE=Release

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
  echo "== Fuzz targets: -fsanitize=fuzzer,address,undefined, ${seconds} s per target"
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
  [ -z "$failed" ] || exit 1
}

if [ "${ANCHORMAP_SKIP_SANITIZE:-0}" != "1" ]; then
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  # Run in the Release pass only (CI's time): the two longest data tests (city10000 against
  # batch, the per-update oracle in iSAM's mode: 3.5 of the pass's minutes under ASan), whose
  # smaller siblings (M3500, the oracle in the server's mode) cover the same code here, and
  # two determinism tests (same input, same map: 70 s under ASan) whose code the merge tests
  # (AgentServerTest.ThreeRobots..., ScanEncountersTest.TwoRobots...) run here.
  export ANCHORMAP_CTEST_EXCLUDE='IncrementalVsBatchTest\.City10000|PerUpdateOracleTest\.IsamMode|AgentServerTest\.OfflineServerOnARecordedLogIsDeterministicAndAgrees|ScanEncountersTest\.SameInputSameMap'
  if why=$(clang_fuzz_missing); then
    echo "== ASan + UBSan build (gcc) and tests; fuzz targets SKIPPED: $why"
    run_pass build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DANCHORMAP_SANITIZE=ON
  else
    echo "== ASan + UBSan build (clang, with the libFuzzer targets) and tests"
    CC=clang CXX=clang++ run_pass build-asan-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DANCHORMAP_SANITIZE=ON -DANCHORMAP_FUZZ=ON
    if [ "${ANCHORMAP_SKIP_FUZZ:-0}" != "1" ]; then
      unset ASAN_OPTIONS UBSAN_OPTIONS
      fuzz_run build-asan-fuzz
    fi
  fi
fi
echo "== all tests passed"
