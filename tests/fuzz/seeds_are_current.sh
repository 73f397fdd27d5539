#!/usr/bin/env bash
# usage: seeds_are_current.sh FUZZ_SEEDS CORPUS_DIR
# Fails when a seed-<n> file in CORPUS_DIR differs from what FUZZ_SEEDS writes now, or is
# missing (inputs libFuzzer added to the corpus, named by their hash, are not compared).
set -euo pipefail
seeds=$1 corpus=$2
fresh=$(mktemp -d)
trap 'rm -rf "$fresh"' EXIT
"$seeds" "$fresh"
status=0
for file in "$fresh"/*/seed-*; do
  relative=${file#"$fresh"/}
  if ! cmp -s "$file" "$corpus/$relative"; then
    echo "stale or missing seed: tests/fuzz/corpus/$relative (regenerate: fuzz-seeds tests/fuzz/corpus)"
    status=1
  fi
done
exit $status
