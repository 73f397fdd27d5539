#!/usr/bin/env bash
# Builds anchormap and runs every test: the README's test command; .ci/run calls it.
#   0. Every C++ file is clang-formatted.
#   1. Release build with warnings as errors, then ctest.
#   2. ASan + UBSan build of the same tests, then ctest.
# Set ANCHORMAP_SKIP_SANITIZE=1 to run only the first pass while iterating locally.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh

jobs=$(nproc)
run_pass() {
  local dir=$1; shift
  cmake -S . -B "$dir" -DANCHORMAP_WERROR=ON "$@" >/dev/null
  cmake --build "$dir" -j "$jobs"
  (cd "$dir" && ctest --output-on-failure -j "$jobs" --timeout 900)
}

echo "== Formatting (clang-format, .clang-format at the root)"
if ! find common agent server tools tests \( -name '*.cc' -o -name '*.h' \) -print0 |
    xargs -0 clang-format --dry-run -Werror; then
  echo "test.sh: files above are not clang-formatted (fix: clang-format -i FILE)" >&2
  exit 1
fi

echo "== Release build (warnings are errors) and tests"
run_pass build -DCMAKE_BUILD_TYPE=Release

if [ "${ANCHORMAP_SKIP_SANITIZE:-0}" != "1" ]; then
  echo "== ASan + UBSan build and tests"
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  run_pass build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DANCHORMAP_SANITIZE=ON
fi
echo "== all tests passed"
