#!/usr/bin/env bash
# A real laser log through the daemons (issue 11, "the same through the daemons"):
#   anchormap-import-carmen LOG --output in.lcmlog [--split N] [--simultaneous]
#   in a private network namespace (multicast on loopback only, ttl=0: nothing leaves it):
#     lcm-logplayer --speed S -> one anchormap-agent per robot -> anchormap-server
#     (its defaults: both scan-matching sources on) -> lcm-logger (out.lcmlog)
#   anchormap-eval --map out.lcmlog --relations RELATIONS --odometry in.lcmlog
# and prints the figures: relation errors (all, and the relations joining two robots),
# across_frames, keyframes, loop closures and scan encounters accepted, how far the server
# was behind when the player finished, x real time, CPU of each agent and of the server.
# With --offline, also the same input through anchormap-replay (all defaults) and the
# daemons' recorded keyframes through anchormap-server --log (its defaults too), so the
# daemons' map can be compared with the offline ones.
# Not a test (a real log takes minutes); no ctest registers it.
#
# usage: tools/bench/daemons_real_log.sh LOG RELATIONS [--split N] [--simultaneous]
#          [--speed S] [--build DIR] [--work DIR] [--offline] [--max-wait-s S]
#   e.g. tools/bench/daemons_real_log.sh ../shared/data/benchmark/intel.clf.gz \
#          ../shared/data/benchmark/intel.relations --split 2 --simultaneous --speed 4
set -uo pipefail

usage() {
  sed -n '17,20p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
}
[ $# -ge 2 ] || usage
[ -f "$1" ] && [ -f "$2" ] || { echo "daemons_real_log: no such file: $1 or $2" >&2; exit 2; }
LOG=$(realpath "$1")
RELATIONS=$(realpath "$2")
shift 2
SPLIT=1
SIMULTANEOUS=""
SPEED=4
BUILD=$(realpath "$(dirname "$0")/../../build")
WORK=""
OFFLINE=0
MAX_WAIT_S=600
while [ $# -gt 0 ]; do
  case $1 in
    --split) SPLIT=$2; shift 2 ;;
    --simultaneous) SIMULTANEOUS=--simultaneous; shift ;;
    --speed) SPEED=$2; shift 2 ;;
    --build) BUILD=$(realpath "$2"); shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    --offline) OFFLINE=1; shift ;;
    --max-wait-s) MAX_WAIT_S=$2; shift 2 ;;
    *) usage ;;
  esac
done
BIN=$BUILD/bin
URL="udpm://239.255.76.67:7667?ttl=0"
TEST_NAME=daemons_real_log
SKIP=77
source "$(dirname "$0")/../../tests/system_test_lib.sh"

require_tools anchormap-import-carmen anchormap-agent anchormap-server anchormap-eval
[ $OFFLINE = 0 ] || require_tools anchormap-replay
command -v /usr/bin/time >/dev/null || { log "/usr/bin/time is missing (package time)"; exit 1; }
require_player_and_netns "the daemons need a private network for their multicast bus"
if [ -z "$WORK" ]; then
  make_work_dir
else
  mkdir -p "$WORK" && WORK=$(realpath "$WORK")
fi

# CPU of a process run under /usr/bin/time -o FILE -f '%U %S %e': user + sys, and wall.
cpu_of() { awk '{ printf "%.1f", $1 + $2 }' "$1"; }

# The run inside the namespace. Every daemon runs under /usr/bin/time (its CPU, with the
# final batch step); GNU time ignores SIGINT while it waits, so the signal goes to its child.
inside_namespace() {
  local work=$1 robots=$2
  ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || return 3
  # (Debian's lcm-logger 1.3.1 refuses -l although its help lists it: use the variable.)
  LCM_DEFAULT_URL="$URL" lcm-logger -c 'ANCHORMAP_.*' -f "$work/out.lcmlog" >"$work/logger.log" 2>&1 &
  local logger=$!
  /usr/bin/time -o "$work/server.time" -f '%U %S %e' "$BIN/anchormap-server" --lcm-url "$URL" \
    --status-period-s 2 >"$work/server.log" 2>&1 &
  local server=$!
  # Trajectory ids 1, 2, ... in robot order, as anchormap-replay gives them: the maps can
  # then be compared pose by pose (the id also breaks ties in the server's canonical order).
  local agents=() r id=0
  for r in $robots; do
    id=$((id + 1))
    /usr/bin/time -o "$work/agent_$r.time" -f '%U %S %e' "$BIN/anchormap-agent" --robot "$r" \
      --trajectory-id $id --lcm-url "$URL" --status-period-s 2 >"$work/agent_$r.log" 2>&1 &
    agents+=($!)
  done
  sleep 1
  log "playing $(basename "$LOG") at ${SPEED}x to robots $robots"
  local start end
  start=$(date +%s.%N)
  lcm-logplayer --speed="$SPEED" -l "$URL" "$work/in.lcmlog" || { log "lcm-logplayer failed"; return 1; }
  end=$(date +%s.%N)
  echo "$start $end" >"$work/player.wall"
  grep 'order: held' "$work/server.log" | tail -1 >"$work/server_at_player_end.txt"
  wait_for_outboxes "$work" "$MAX_WAIT_S" || return 1
  # The server has everything; wait until it has put it all into the graph (its status
  # line: nothing held by the canonical order or waiting for a gap), every 2 s.
  local waited=0 line
  while :; do
    sleep 2
    waited=$((waited + 2))
    line=$(grep 'order: held' "$work/server.log" | tail -1)
    echo "$line" | grep -q 'waiting keyframes 0 .*order: held 0 ' && break
    [ $waited -lt "$MAX_WAIT_S" ] || { log "the server still holds inputs after $MAX_WAIT_S s"; break; }
  done
  echo "$(date +%s.%N)" >"$work/drained.wall"
  local pid status=0
  for pid in "${agents[@]}"; do kill -INT "$(pgrep -P "$pid")"; done
  for pid in "${agents[@]}"; do wait "$pid" || { log "an agent did not exit cleanly"; status=1; }; done
  sleep 2  # the last maps go out
  kill -INT "$(pgrep -P "$server")"
  wait "$server" || { log "the server did not exit cleanly"; status=1; }
  sleep 0.5
  kill -INT "$logger"
  wait "$logger"
  return $status
}

# relation_figures EVAL_JSON RELATION_ERRORS: one line of the figures, and of the relations
# whose two ends lie in different robots' pieces (from the importer's summary in import.txt).
relation_figures() {
  python3 - "$1" "$2" "$WORK/import.txt" <<'EOF'
import json, re, sys
report = json.load(open(sys.argv[1]))
# The pieces on the relations' clock: each robot's span, shifted back by its --simultaneous shift.
spans, text = [], open(sys.argv[3]).read().splitlines()
for i, line in enumerate(text):
    m = re.match(r'\s*robot (\S+) .* ([0-9.]+) \.\. ([0-9.]+) s;', line)
    if not m:
        continue
    shift = 0.0
    if i + 1 < len(text):
        s = re.search(r'shifted by (-?[0-9.]+) s', text[i + 1])
        if s and not re.match(r'\s*robot ', text[i + 1]):
            shift = float(s.group(1))
    spans.append((float(m.group(2)) - shift, float(m.group(3)) - shift))
def piece(t):
    for k, (a, b) in enumerate(spans):
        if a - 1e-3 <= t <= b + 1e-3:
            return k
    return -1
joining = []
for line in open(sys.argv[2]):
    f = line.split()
    if len(f) < 5:
        continue
    t1, t2, err_t, err_r = float(f[0]), float(f[1]), float(f[3]), float(f[4])
    if piece(t1) != piece(t2):
        joining.append((err_t, err_r))
t, r, skipped = report["translation_m"], report["rotation_rad"], report["skipped"]
print("relations %d evaluated %d across_frames %d outside_span %d no_pose_near %d" %
      (report["relations"], report["evaluated"], skipped["across_frames"],
       skipped["outside_span"], skipped["no_pose_near"]))
print("translation mean %.4f m median %.4f max %.4f; rotation mean %.4f rad (%.3f deg)" %
      (t["mean"], t["median"], t["max"], r["mean"], r["mean"] * 57.29577951308232))
if len(spans) > 1:
    n = len(joining)
    mt = sum(e[0] for e in joining) / n if n else float('nan')
    mr = sum(e[1] for e in joining) / n if n else float('nan')
    print("joining two robots: %d relations, translation mean %.4f m, rotation mean %.4f rad" % (n, mt, mr))
EOF
}

# evaluate NAME MAP: anchormap-eval of MAP against the relations; prints the figures.
evaluate() {
  "$BIN/anchormap-eval" --map "$2" --relations "$RELATIONS" --odometry "$WORK/in.lcmlog" --json \
    --relation-errors "$WORK/$1.rel" >"$WORK/$1.eval.json" 2>"$WORK/$1.eval.err" ||
    { log "anchormap-eval failed on $2"; cat "$WORK/$1.eval.err"; return 1; }
  relation_figures "$WORK/$1.eval.json" "$WORK/$1.rel" | sed "s/^/$1: /"
}

# The scan-matching sources' counts in a server's final status line.
source_counts() {
  grep 'final:' "$1" | tail -1 | grep -oE '(loop|scan): candidates [0-9]+ accepted [0-9]+' |
    tr '\n' ';' | sed 's/;$//'
}

main() {
  log "importing $(basename "$LOG") (--split $SPLIT $SIMULTANEOUS)"
  "$BIN/anchormap-import-carmen" "$LOG" --output "$WORK/in.lcmlog" --split "$SPLIT" $SIMULTANEOUS \
    >"$WORK/import.txt" 2>&1 || { log "import failed"; cat "$WORK/import.txt"; exit 1; }
  local robots duration
  robots=$(sed -nE 's/^\s*robot (\S+) .*/\1/p' "$WORK/import.txt" | tr '\n' ' ')
  # Data time played: the longest robot's span (the pieces play together with --simultaneous).
  duration=$(sed -nE 's/^\s*robot \S+ .* ([0-9.]+) \.\. ([0-9.]+) s;.*/\1 \2/p' "$WORK/import.txt" |
    awk 'NR == 1 || $1 < lo { lo = $1 } NR == 1 || $2 > hi { hi = $2 } END { printf "%.1f", hi - lo }')
  log "robots: $robots; data time ${duration} s; load average $(cut -d' ' -f1-3 /proc/loadavg)"

  export -f inside_namespace outboxes_show outboxes_empty wait_for_outboxes log
  export BIN URL SPEED MAX_WAIT_S TEST_NAME LOG
  unshare -n bash -c "inside_namespace '$WORK' '$robots'"
  local status=$?
  [ $status -eq 0 ] || { log "the daemons failed (status $status)"; tail -5 "$WORK/server.log"; exit 1; }
  log "load average after the run $(cut -d' ' -f1-3 /proc/loadavg)"

  local start end drained played total
  read -r start end <"$WORK/player.wall"
  drained=$(cat "$WORK/drained.wall")
  played=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.1f", b - a }')
  total=$(awk -v a="$start" -v b="$drained" 'BEGIN { printf "%.1f", b - a }')
  echo "== daemons (lcm-logplayer --speed $SPEED; server with its defaults)"
  echo "player: ${played} s for ${duration} s of data ($(awk -v d="$duration" -v p="$played" \
    'BEGIN { printf "%.2f", d / p }')x); server done ${total} s after the start ($(awk -v d="$duration" \
    -v p="$total" 'BEGIN { printf "%.2f", d / p }')x real time)"
  echo "server's canonical order stage held at most $(grep -oE 'order: held [0-9]+' "$WORK/server.log" |
    awk '$3 > m { m = $3 } END { print m + 0 }') inputs (status lines every 2 s)"
  echo "server when the player ended: $(sed -nE 's/.*(keyframes [0-9]+ encounters [0-9]+) .*(waiting keyframes [0-9]+).*(order: held [0-9]+).*/\1, \2, \3/p' \
    "$WORK/server_at_player_end.txt")"
  local r
  for r in $robots; do
    echo "agent $r: cpu $(cpu_of "$WORK/agent_$r.time") s; $(grep 'final:' "$WORK/agent_$r.log" | tail -1 |
      sed -nE 's/.*(odometry [0-9]+ scans [0-9]+ keyframes [0-9]+).*(resent [0-9+]+).*(scan matching: matched [0-9/]+ odometry [0-9]+).*(cpu [0-9.]+ ms\/scan).*(rejected: [^|]*).*(lcm max burst [0-9]+( kernel drops [0-9-]+)?).*/\1, \2, \3, \4, \5, \6/p')"
  done
  local cpu_all
  cpu_all=$(cat "$WORK"/agent_*.time "$WORK/server.time" | awk '{ s += $1 + $2 } END { printf "%.1f", s }')
  echo "cpu of all daemons ${cpu_all} s: $(awk -v d="$duration" -v c="$cpu_all" 'BEGIN { printf "%.1f", d / c }')x real time on CPU"
  echo "server: cpu $(cpu_of "$WORK/server.time") s; $(grep 'final:' "$WORK/server.log" | tail -1 |
    sed -nE 's/.*(anchored [0-9]+ keyframes [0-9]+ encounters [0-9]+).*(bridged gaps [0-9]+).*(order: held [0-9]+ late [0-9]+ silences [0-9]+) (rejected: [^;]*).*(kernel drops [0-9-]+).*/\1, \2, \3, \4, \5/p')"
  echo "server sources: $(source_counts "$WORK/server.log")"
  evaluate daemons "$WORK/out.lcmlog" || exit 1

  if [ $OFFLINE = 1 ]; then
    echo "== offline: anchormap-replay (all defaults) on the same import"
    /usr/bin/time -o "$WORK/replay.time" -f '%U %S %e' "$BIN/anchormap-replay" --log "$WORK/in.lcmlog" \
      --output "$WORK/replay.lcmlog" --inputs-output "$WORK/replay_inputs.lcmlog" >"$WORK/replay.log" 2>&1 ||
      { log "anchormap-replay failed"; tail -5 "$WORK/replay.log"; exit 1; }
    echo "replay: cpu $(cpu_of "$WORK/replay.time") s; $(grep 'server:' "$WORK/replay.log" | tail -1 |
      sed -nE 's/.*(anchored [0-9]+ keyframes [0-9]+ encounters [0-9]+).*/\1/p'); $(grep 'server:' "$WORK/replay.log" |
      tail -1 | grep -oE '(loop|scan): candidates [0-9]+ accepted [0-9]+' | tr '\n' ';')"
    evaluate replay "$WORK/replay.lcmlog" || exit 1
    echo "== offline: anchormap-server --log on the daemons' recorded keyframes (its defaults)"
    /usr/bin/time -o "$WORK/server_offline.time" -f '%U %S %e' "$BIN/anchormap-server" \
      --log "$WORK/out.lcmlog" --output "$WORK/server_offline.lcmlog" >"$WORK/server_offline.log" 2>&1 ||
      { log "anchormap-server --log failed"; tail -5 "$WORK/server_offline.log"; exit 1; }
    echo "server --log: cpu $(cpu_of "$WORK/server_offline.time") s; $(source_counts "$WORK/server_offline.log")"
    evaluate server_offline "$WORK/server_offline.lcmlog" || exit 1
    if [ -x "$BIN/anchormap-test-compare-maps" ]; then
      echo "== the daemons' final map against the offline ones (\"doubled\": encounters between one keyframe pair, in both)"
      "$BIN/anchormap-test-compare-maps" --map "$WORK/out.lcmlog" --reference "$WORK/replay.lcmlog" \
        --tolerance 1e-6 | grep -E 'keyframes .*reference' | sed 's/^/against replay: /'
      "$BIN/anchormap-test-compare-maps" --map "$WORK/out.lcmlog" --reference "$WORK/server_offline.lcmlog" \
        --tolerance 1e-6 | grep -E 'keyframes .*reference' | sed 's/^/against server --log: /'
    fi
  fi
}

main
