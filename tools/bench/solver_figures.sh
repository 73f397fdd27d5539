#!/usr/bin/env bash
# Prints the solver's benchmark figures (the solver issue's closing table) as markdown:
# M3500 and city10000, incremental (solution after every step) and batch, exact and
# thresholded back-substitution; iterations to 1e-4 for relative vs global formulations
# on 2- and 3-robot splits (docs/METHOD.md section 9: batch steps only every 100 updates, as the
# iSAM 1.6 reference, so no fill-triggered ones, each iterated to convergence). Run on a
# quiet machine after a Release build:
#
#   tools/bench/solver_figures.sh [DATA_DIR]     (default ../shared/data or $ANCHORMAP_DATA_DIR)
#
# Further tables: broken odometry chains (--break-chain), the server configuration
# (--relinearize 0.01, partial vs --full-relinearization, --check-every 37), and CPU
# seconds against Kaess's iSAM 1.7 (../shared/anchors/isam1.sh) in the same run: iSAM1's
# mode, the server's, and the server's with the correction by conjugate gradients, medians
# of REPEAT interleaved runs (city10000 only with CITY=1: minutes per run).
#
# "total s" in the first table is the median of REPEAT runs (default 3; this machine kind
# is noisy); the step times come from the last run, and the other columns are the same
# in every run.
set -euo pipefail
cd "$(dirname "$0")/../.."
DATA=${1:-${ANCHORMAP_DATA_DIR:-../shared/data}}/posegraph
BENCH=build/bin/anchormap-bench-solver
[ -x "$BENCH" ] || { echo "solver_figures: build first (scripts/test.sh or cmake --build build)" >&2; exit 1; }
[ -d "$DATA" ] || { echo "solver_figures: no pose graphs in $DATA; skipping" >&2; exit 0; }

REPEAT=${REPEAT:-3}
field() { grep -o "\"$2\": [^,}]*" <<<"$1" | head -n 1 | sed 's/.*: //; s/"//g'; }

echo "| graph | mode | back-sub threshold | total s | step median ms | step p99 ms | batch steps | chi2 at the end | chi2 after a final batch step | its rel. diff to the batch optimum | nnz/column |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for graph in M3500 city10000; do
  [ -f "$DATA/$graph.g2o" ] || { echo "| $graph | (absent) |||||||||"; continue; }
  for run in "batch 0" "incremental 0" "incremental 0.001" "incremental 0.01"; do
    set -- $run
    times=()
    for ((k = 0; k < REPEAT; ++k)); do
      j=$("$BENCH" "$DATA/$graph.g2o" --mode "$1" --threshold "$2" --json)
      times+=("$(field "$j" total_s)")
    done
    median=$(printf '%s\n' "${times[@]}" | sort -g | sed -n "$(((REPEAT + 1) / 2))p")
    echo "| $graph | $1 | $2 | $median | $(field "$j" step_median_ms) |" \
      "$(field "$j" step_p99_ms) | $(field "$j" batch_steps) | $(field "$j" chi2) |" \
      "$(field "$j" chi2_after_final_batch) |" \
      "$(field "$j" chi2_relative_difference) | $(field "$j" nnz_per_column) |"
  done
done

echo
echo "| graph | robots | formulation | iterations_to_1e-4 | batch steps | chi2 at the end | chi2 after a final batch |"
echo "|---|---|---|---|---|---|---|"
for graph in M3500 intel; do
  [ -f "$DATA/$graph.g2o" ] || continue
  for robots in 2 3; do
    for formulation in relative global global-moved; do
      j=$("$BENCH" "$DATA/$graph.g2o" --robots "$robots" --formulation "$formulation" \
        --converge-batches --fill-factor 0 --no-reference --json)
      echo "| $graph | $robots | $formulation | $(field "$j" 'iterations_to_1e-4') |" \
        "$(field "$j" batch_steps) | $(field "$j" chi2) | $(field "$j" chi2_after_final_batch) |"
    done
  done
done

echo
echo "Broken odometry chains (M3500 with odometry edges dropped; each break starts a trajectory in its own frame):"
echo
echo "| graph | dropped odometry into | mode | trajectories | encounters | chi2 after a final batch step | batch optimum | rel. diff |"
echo "|---|---|---|---|---|---|---|---|"
if [ -f "$DATA/M3500.g2o" ]; then
  for breaks in "1000" "1000 2500"; do
    args=()
    for b in $breaks; do args+=(--break-chain "$b"); done
    for mode in incremental batch; do
      j=$("$BENCH" "$DATA/M3500.g2o" --mode "$mode" "${args[@]}" --json)
      echo "| M3500 | ${breaks// /, } | $mode | $(field "$j" trajectories) | $(field "$j" encounters) |" \
        "$(field "$j" chi2_after_final_batch) | $(field "$j" chi2_batch_optimum) | $(field "$j" chi2_relative_difference) |"
    done
  done
fi

echo
echo "Server configuration (relinearise at 0.01): partial relinearisation vs a full batch step on drift;"
echo "every 37th step checked against the batch optimum of the edges so far (untimed):"
echo
echo "(per partial step: the rows re-eliminated; the rows marked before the elimination-tree closure;"
echo "the rows from the first of them to the end of R, which a column-ordered re-elimination would redo)"
echo
echo "| graph | on drift | total s | partial steps | batch steps | rows re-eliminated per partial step | marked before closure | tail from the first | worst checked step chi2 excess | chi2 at the end |"
echo "|---|---|---|---|---|---|---|---|---|---|"
if [ -f "$DATA/M3500.g2o" ]; then
  for how in partial full; do
    extra=()
    [ "$how" = full ] && extra=(--full-relinearization)
    j=$("$BENCH" "$DATA/M3500.g2o" --relinearize 0.01 "${extra[@]}" --check-every 37 --no-reference --json)
    partial=$(field "$j" partial_relinearizations)
    rows=$(field "$j" rows_reeliminated)
    per() { [ "$partial" -gt 0 ] && echo $(($1 / partial)) || echo -; }
    echo "| M3500 | $how | $(field "$j" total_s) | $partial | $(field "$j" batch_steps) | $(per "$rows") |" \
      "$(per "$(field "$j" rows_before_closure)") | $(per "$(field "$j" rows_in_tails)") |" \
      "$(field "$j" worst_step_chi2_excess) | $(field "$j" chi2) |"
  done
fi

echo
echo "The server's mode (--server-mode: relinearise at 0.01 by partial steps, merges by partial"
echo "steps, no batch step on a clock) against the server's old policy (a batch step every 10"
echo "updates), 1 and 4 robots; every 37th step checked (untimed):"
echo
echo "| graph | robots | policy | total s | batch steps | partial steps | partial merges | worst checked step chi2 excess | chi2 after a final batch step |"
echo "|---|---|---|---|---|---|---|---|---|"
if [ -f "$DATA/M3500.g2o" ]; then
  for robots in 1 4; do
    for policy in "--relinearize 0.01 --batch-every 10" "--server-mode"; do
      j=$("$BENCH" "$DATA/M3500.g2o" --robots "$robots" $policy --check-every 37 --no-reference --json)
      echo "| M3500 | $robots | $policy | $(field "$j" total_s) | $(field "$j" batch_steps) |" \
        "$(field "$j" partial_relinearizations) | $(field "$j" partial_merges) |" \
        "$(field "$j" worst_step_chi2_excess) | $(field "$j" chi2_after_final_batch) |"
    done
  done
fi

echo
echo "The correction's work per update (the server's mode with the CG correction): gradient passes"
echo "linearise only factors whose variables moved (the entry pass: the new factors); the Givens"
echo "update does not back-substitute (R only preconditions; partial steps do); every 37th step"
echo "checked (untimed):"
echo
echo "| graph | robots | CG iterations | gradient passes | factors linearised per pass | factors | rows back-substituted per update | worst checked step chi2 excess | chi2 at the end |"
echo "|---|---|---|---|---|---|---|---|---|"
if [ -f "$DATA/M3500.g2o" ]; then
  for robots in 1 16; do
    j=$("$BENCH" "$DATA/M3500.g2o" --robots "$robots" --server-mode --correct 1e-4 --relinearize-on-stall \
      --correct-cg 50 --check-every 37 --no-reference --json)
    passes=$(field "$j" gradient_passes)
    echo "| M3500 | $robots | $(field "$j" correction_steps) | $passes |" \
      "$(awk -v a="$(field "$j" factors_linearized_by_passes)" -v b="$passes" 'BEGIN { printf "%.0f", a / (b > 0 ? b : 1) }') |" \
      "$(field "$j" factors) | $(field "$j" rows_backsubstituted_per_step) |" \
      "$(field "$j" worst_step_chi2_excess) | $(field "$j" chi2) |"
  done
fi

ISAM1=${ISAM1:-../shared/anchors/isam1.sh}
if [ -x "$ISAM1" ] || [ -f "$ISAM1" ]; then
  echo
  echo "CPU seconds against iSAM 1.7 (\`$ISAM1\`, Gauss-Newton, batch step every 100), medians of"
  echo "$REPEAT interleaved runs; ratio = ours / iSAM1 of the same runs:"
  echo
  echo "| graph | our mode | ours CPU s | iSAM1 CPU s | ratio | our chi2 at the end |"
  echo "|---|---|---|---|---|---|"
  # The server's mode with the correction by conjugate gradients (R only preconditions).
  CG_FLAGS=(--server-mode --correct 1e-4 --relinearize-on-stall --correct-cg 50)
  median() { printf '%s\n' "$@" | sort -g | sed -n "$((($# + 1) / 2))p"; }
  graphs=(M3500)
  [ "${CITY:-0}" = 1 ] && graphs+=(city10000)
  for graph in "${graphs[@]}"; do
    [ -f "$DATA/$graph.g2o" ] || continue
    iron=() server=() cg=() isam=()
    for ((k = 0; k < REPEAT; ++k)); do
      j=$("$BENCH" "$DATA/$graph.g2o" --no-reference --json)
      iron+=("$(field "$j" total_cpu_s)")
      iron_chi2=$(field "$j" chi2)
      j=$("$BENCH" "$DATA/$graph.g2o" --server-mode --no-reference --json)
      server+=("$(field "$j" total_cpu_s)")
      server_chi2=$(field "$j" chi2)
      j=$("$BENCH" "$DATA/$graph.g2o" "${CG_FLAGS[@]}" --no-reference --json)
      cg+=("$(field "$j" total_cpu_s)")
      cg_chi2=$(field "$j" chi2)
      isam+=("$(field "$(bash "$ISAM1" "$DATA/$graph.g2o")" total_cpu_s)")
    done
    reference=$(median "${isam[@]}")
    for mode in isam1 server cg; do
      if [ "$mode" = isam1 ]; then ours=$(median "${iron[@]}") chi2=$iron_chi2 label="iSAM1's (default)"
      elif [ "$mode" = server ]; then ours=$(median "${server[@]}") chi2=$server_chi2 label="--server-mode"
      else ours=$(median "${cg[@]}") chi2=$cg_chi2 label="${CG_FLAGS[*]}"; fi
      ratio=$(awk -v a="$ours" -v b="$reference" 'BEGIN { printf "%.2f", a / b }')
      echo "| $graph | $label | $ours | $reference | $ratio | $chi2 |"
    done
  done
fi
