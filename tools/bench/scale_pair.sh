#!/usr/bin/env bash
# A same-minute A/B of two builds on one simulated team (issue 12's scale figures): both
# replays run at once, one pinned to each of the machine's first two cores, so both see the
# same minute's speed (this VM's speed drifts by tens of percent between minutes; its cores
# differ too: run it twice with A and B swapped). Prints per build the CPU seconds
# (user + sys), the solver's share (sum of the server's update CPU), the update median, p99
# and max, the updates >= 100 ms, and the merged ATE against the simulation's truth; then
# whether the two outputs are byte-identical.
#
#   tools/bench/scale_pair.sh BIN_A BIN_B SIM [WORK_DIR]
#
# BIN_A, BIN_B: build/bin folders of the two builds; SIM: an `anchormap-sim` log (e.g.
# `anchormap-sim --robots 100 --duration-s 180 --seed 2 --output SIM`). The replay is
# scale_figures.sh's (agents' scan matching off, the server's sources on).
set -euo pipefail
[ $# -ge 3 ] || { sed -n 2,14p "$0" | sed 's/^# \{0,1\}//'; exit 2; }
A=$1 B=$2 SIM=$3
WORK=${4:-$(mktemp -d)}
mkdir -p "$WORK"
for bin in "$A" "$B"; do
  [ -x "$bin/anchormap-replay" ] && [ -x "$bin/anchormap-eval" ] ||
    { echo "scale_pair: no anchormap-replay / anchormap-eval in $bin" >&2; exit 1; }
done
[ -r "$SIM" ] || { echo "scale_pair: cannot read $SIM" >&2; exit 1; }

replay() {  # BIN CORE TAG
  /usr/bin/time -f "%U %S" -o "$WORK/time-$3.txt" taskset -c "$2" "$1/anchormap-replay" \
    --log "$SIM" --output "$WORK/out-$3.lcmlog" --update-times "$WORK/updates-$3.csv" \
    --log-level warning --scan-matching false --loop-closures true --scan-encounters true \
    > "$WORK/replay-$3.txt" 2>&1
}
replay "$A" 0 a & pid_a=$!
replay "$B" 1 b & pid_b=$!
wait "$pid_a" "$pid_b"

for tag in a b; do
  bin=$A; [ "$tag" = b ] && bin=$B
  ate=$("$bin/anchormap-eval" --map "$WORK/out-$tag.lcmlog" --truth "$SIM" --json |
    python3 -c "import json,sys; print(round(json.load(sys.stdin)['merged']['ate']['translation_m']['rmse'],4))")
  cpu=$(awk '{printf "%.1f", $1 + $2}' "$WORK/time-$tag.txt")
  awk -F, 'NR > 1 {print $5}' "$WORK/updates-$tag.csv" | sort -g |
    awk -v name="$bin" -v cpu="$cpu" -v ate="$ate" '
      {v[NR] = $1; s += $1; if ($1 >= 100) n++}
      END {printf "%s: CPU %s s, solver %.1f s, update median %.1f p99 %.1f max %.1f ms, >= 100 ms %d of %d, merged ATE %s m\n",
           name, cpu, s / 1000, v[int((NR + 1) / 2)], v[int(0.99 * NR + 0.999999)], v[NR], n, NR, ate}'
done
if cmp -s "$WORK/out-a.lcmlog" "$WORK/out-b.lcmlog"; then echo "outputs: byte-identical"; else echo "outputs: differ"; fi
echo "files: $WORK"
