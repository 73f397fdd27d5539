#!/usr/bin/env bash
# Prints the server's scale figures (issue 12) as markdown: simulated teams replayed through
# agents + server in one process (anchormap-replay, pinned to one core), the replay's speed
# against real time, and the cost of every solver update (median, p99, max), overall and per
# sixth of the run and per slice of data time (SCALE_SLICE_S, default 300 s: median, p99 and
# the replay's speed per slice), so that growth with the map shows, and the process's maximum
# RSS. Run on a quiet machine after a Release build:
#
#   tools/bench/scale_figures.sh [RUNS...]     RUN = ROBOTSxSECONDS
#                                              (default: 100x180 20x1800, the issue's two)
#
# The simulator's seed is 2; files go to a temporary folder (ANCHORMAP_KEEP_TEST_DIR=1
# keeps them; SCALE_SIM_DIR=DIR takes DIR/sim-RUN.lcmlog from such a run instead of simulating
# again). AGENT_SCAN_MATCHING=false replays with the agents' scan matching off (it
# runs in the same process and, at 100 robots, costs more than the server); "solver s"
# is the sum of the server's update times, whatever the agents do. Update times are the
# server thread's CPU time per update (wall time when the replay predates that column).
# SERVER_SOURCES=false turns the server's loop closures and scan encounters off (at 100 robots their global
# searches of unjoined trajectories dominate the start of the run). SERVER_FLAGS="..." adds
# flags to the replay (e.g. "--solve-period-s 0": one solver update per input). After the table: the
# bytes of the server's outputs per channel for each run (tools/bench/log_bytes.py).
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=build/bin
TOOLS=(anchormap-replay)
[ -n "${SCALE_SIM_DIR:-}" ] || TOOLS+=(anchormap-sim)
for tool in "${TOOLS[@]}"; do
  [ -x "$BIN/$tool" ] || { echo "scale_figures: build first (cmake --build build)" >&2; exit 1; }
done
RUNS=("$@")
[ ${#RUNS[@]} -gt 0 ] || RUNS=(100x180 20x1800)
WORK=$(mktemp -d "${TMPDIR:-/tmp}/anchormap-scale.XXXXXX")
if [ "${ANCHORMAP_KEEP_TEST_DIR:-0}" = "1" ]; then
  echo "scale_figures: files in $WORK" >&2
else
  trap "rm -rf '$WORK'" EXIT
fi
PIN=()
command -v taskset >/dev/null && PIN=(taskset -c "${SCALE_CPU:-0}")  # SCALE_CPU: the core (default 0)

# "median p99 max" of the numbers on stdin (nearest rank).
percentiles() {
  sort -g | awk '{ v[NR] = $1 } END {
    if (NR == 0) { print "- - -"; exit }
    m = int((NR + 1) / 2); p = int(0.99 * NR + 0.999999); if (p < 1) p = 1
    printf "%.2f %.2f %.2f\n", v[m], v[p], v[NR] }'
}

# The CSV column of an update's cost: the server thread's CPU ms (5) when the replay wrote
# it, else the wall ms (2), which on a loaded machine also counts the waits for a core.
update_column() { head -n 1 "$1" | grep -q update_cpu_ms && echo 5 || echo 2; }

# The update times per slice of data time (default 300 s): "start-end s | updates | median |
# p99 | x real time (CPU) over the slice" rows, from the CSV's data_s, update_ms, cpu_s.
slices() {
  awk -F, -v w="${SCALE_SLICE_S:-300}" -v UPDATE_COLUMN="$(update_column "$1")" 'NR > 1 {
      k = int($1 / w); n[k]++; v[k, n[k]] = $UPDATE_COLUMN; if (!(k in c0)) c0[k] = $4; c1[k] = $4
      d1[k] = $1
      if (k > last) last = k }
    END {
      for (k = 0; k <= last; k++) {
        if (n[k] == 0) continue
        m = n[k]; for (i = 1; i <= m; i++) a[i] = v[k, i]
        # insertion sort is enough for a few thousand values per slice
        for (i = 2; i <= m; i++) { x = a[i]; j = i - 1; while (j > 0 && a[j] > x) { a[j + 1] = a[j]; j-- } a[j + 1] = x }
        med = a[int((m + 1) / 2)]; p = int(0.99 * m + 0.999999); if (p < 1) p = 1
        start = k > 0 && ((k - 1) in c1) ? c1[k - 1] : c0[k]
        # the last slice may be partial: its data span ends at its last update
        span = k < last ? w : d1[k] - k * w
        cpu = c1[k] - start; speed = cpu > 0 ? sprintf("%.2f", span / cpu) : "-"
        printf "| %d-%d | %d | %.2f | %.2f | %s |\n", k * w, (k + 1) * w, m, med, a[p], speed }
    }' "$1"
}

echo "| robots | data s | agents' scan matching | server sources | keyframes | updates | batch steps | replay wall s | CPU s | max RSS MB | x real time (wall) | x real time (CPU) | solver s | update median ms | p99 ms | max ms | p99 ms per sixth of the run |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for run in "${RUNS[@]}"; do
  robots=${run%x*}
  seconds=${run#*x}
  log="$WORK/sim-$run.lcmlog"
  if [ -f "${SCALE_SIM_DIR:-/nonexistent}/sim-$run.lcmlog" ]; then
    log="$SCALE_SIM_DIR/sim-$run.lcmlog"  # the same simulation, made by an earlier run
  else
    "$BIN/anchormap-sim" --robots "$robots" --seed 2 --duration-s "$seconds" --output "$log" \
      >"$WORK/sim-$run.txt"
  fi
  csv="$WORK/updates-$run.csv"
  /usr/bin/time -f "%e %U %S %M" -o "$WORK/time-$run.txt" "${PIN[@]}" "$BIN/anchormap-replay" \
    --log "$log" --output "$WORK/out-$run.lcmlog" --update-times "$csv" --log-level info \
    --scan-matching "${AGENT_SCAN_MATCHING:-true}" \
    --loop-closures "${SERVER_SOURCES:-true}" --scan-encounters "${SERVER_SOURCES:-true}" \
    ${SERVER_FLAGS:-} >"$WORK/replay-$run.txt" 2>&1 ||
    { echo "scale_figures: replay of $run failed" >&2; tail "$WORK/replay-$run.txt" >&2; exit 1; }
  read -r wall user sys rss_kb <"$WORK/time-$run.txt"
  rss_mb=$((rss_kb / 1024))
  cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.1f", u + s }')
  factor=$(awk -v d="$seconds" -v w="$wall" 'BEGIN { printf "%.2f", d / w }')
  # On a loaded machine the wall time says little: data seconds per CPU second (one core).
  cpu_factor=$(awk -v d="$seconds" -v c="$cpu" 'BEGIN { printf "%.2f", d / c }')
  keyframes=$(grep 'server: ' "$WORK/replay-$run.txt" | grep -o 'keyframes [0-9]*' | head -1 |
    grep -o '[0-9]*' || echo "?")
  updates=$(($(wc -l <"$csv") - 1))
  batch=$(awk -F, 'NR > 1 && $3 == 1' "$csv" | wc -l)
  col=$(update_column "$csv")
  read -r median p99 max < <(awk -F, -v c="$col" 'NR > 1 { print $c }' "$csv" | percentiles)
  solver=$(awk -F, -v c="$col" 'NR > 1 { s += $c } END { printf "%.1f", s / 1000 }' "$csv")
  sixths=""
  for k in 0 1 2 3 4 5; do
    part=$(awk -F, -v k=$k -v d="$seconds" -v c="$col" 'NR > 1 && int(6 * $1 / d) == k { print $c }' "$csv" |
      percentiles | cut -d' ' -f2)
    sixths="$sixths${sixths:+ / }$part"
  done
  echo "| $robots | $seconds | ${AGENT_SCAN_MATCHING:-true} | ${SERVER_SOURCES:-true} | $keyframes | $updates | $batch | $wall | $cpu | $rss_mb | $factor | $cpu_factor |" \
    "$solver | $median | $p99 | $max | $sixths |"
  if command -v python3 >/dev/null; then
    python3 tools/bench/log_bytes.py "$WORK/out-$run.lcmlog" "$seconds" >"$WORK/bytes-$run.md"
  fi
done
echo
for run in "${RUNS[@]}"; do
  # The scan sources' own figures (loop closures, scan encounters: global searches run).
  echo "Server sources of $run: $(grep -o 'loop: .*' "$WORK/replay-$run.txt" | tail -1)"
done
for run in "${RUNS[@]}"; do
  # Flat or not as the map grows: the update times and the replay's speed per slice.
  echo
  echo "Update times of $run per ${SCALE_SLICE_S:-300} s of data:"
  echo
  echo "| data s | updates | median ms | p99 ms | x real time (CPU) |"
  echo "|---|---|---|---|---|"
  slices "$WORK/updates-$run.csv"
done
for run in "${RUNS[@]}"; do
  [ -f "$WORK/bytes-$run.md" ] || continue
  echo
  echo "Server outputs of $run (bytes per channel, per data second):"
  echo
  cat "$WORK/bytes-$run.md"
done
