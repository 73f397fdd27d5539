#!/usr/bin/env bash
# The viewer's load figure (issue 14; a benchmark, not a test): 100 simulated robots,
# their server outputs replayed at real time through anchormap-viewer to a headless
# Chromium, in a private network namespace. Prints the viewer's CPU, the WebSocket bytes
# per second to the one browser, and the page's frame time with everything drawn.
#
#   tools/bench/viewer_load.sh [--robots 100] [--duration-s 60] [--seed 2] [--work DIR]
#
# Needs a Release build of anchormap-sim, anchormap-replay, anchormap-viewer and
# anchormap-test-viewer-browser, and chromium. The replay of 100 robots takes minutes.
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$(pwd)
BIN=$ROOT/build/bin
ROBOTS=100
DURATION_S=60
SEED=2
WORK=""
while [ $# -gt 0 ]; do
  case "$1" in
    --robots) ROBOTS=$2; shift 2 ;;
    --duration-s) DURATION_S=$2; shift 2 ;;
    --seed) SEED=$2; shift 2 ;;
    --work) WORK=$2; shift 2 ;;
    *) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 2 ;;
  esac
done
CHROMIUM=$(command -v chromium || true)
[ -n "$CHROMIUM" ] || { echo "viewer_load: no chromium" >&2; exit 1; }
for tool in anchormap-sim anchormap-replay anchormap-viewer anchormap-test-viewer-browser; do
  [ -x "$BIN/$tool" ] || { echo "viewer_load: build $tool first" >&2; exit 1; }
done
[ -n "$WORK" ] || WORK=$(mktemp -d "${TMPDIR:-/tmp}/anchormap-viewer-load.XXXXXX")
mkdir -p "$WORK"
URL="udpm://239.255.76.67:7692?ttl=0"
HTTP_PORT=18089

if [ ! -s "$WORK/out.lcmlog" ]; then
  echo "viewer_load: simulating $ROBOTS robots for $DURATION_S s (seed $SEED)"
  "$BIN/anchormap-sim" --robots "$ROBOTS" --duration-s "$DURATION_S" --seed "$SEED" \
    --output "$WORK/sim.lcmlog" >"$WORK/sim.txt"
  echo "viewer_load: anchormap-replay (agents + server) -> server outputs"
  /usr/bin/time -f "viewer_load: replay took %e s" "$BIN/anchormap-replay" --log "$WORK/sim.lcmlog" \
    --output "$WORK/out.lcmlog" --publish-period-s 1 --grid-period-s 2 --log-level warning
fi

measure() {
  set -euo pipefail
  sysctl -qw net.core.rmem_max=8388608 2>/dev/null || true
  "$BIN/anchormap-viewer" --lcm-url "$URL&recv_buf_size=8388608" --http-port $HTTP_PORT \
    --status-period-s 10 >"$WORK/viewer.log" 2>&1 &
  local viewer=$!
  for _ in $(seq 1 100); do (exec 3<>/dev/tcp/127.0.0.1/$HTTP_PORT) 2>/dev/null && break; sleep 0.1; done
  "$CHROMIUM" --headless=new --no-sandbox --disable-gpu --no-first-run --hide-scrollbars \
    --remote-debugging-address=127.0.0.1 --remote-debugging-port=9311 \
    --user-data-dir="$WORK/browser" --window-size=1400,900 "http://127.0.0.1:$HTTP_PORT/" \
    >"$WORK/browser.log" 2>&1 &
  local browser=$!
  "$BIN/anchormap-test-viewer-browser" --devtools-port 9311 --viewer-port $HTTP_PORT \
    --min-map-update -1 --timeout-s 60 --state-out "$WORK/state0.json" >/dev/null
  local ticks0 t0 ticks1 t1
  ticks0=$(awk '{ print $14 + $15 }' /proc/$viewer/stat)
  t0=$(date +%s.%N)
  lcm-logplayer --speed=1 -l "$URL" "$WORK/out.lcmlog"
  t1=$(date +%s.%N)
  ticks1=$(awk '{ print $14 + $15 }' /proc/$viewer/stat)
  "$BIN/anchormap-test-viewer-browser" --devtools-port 9311 --viewer-port $HTTP_PORT \
    --timeout-s 120 --state-out "$WORK/state1.json" --screenshot-out "$WORK/load.png" \
    --draw-times 30 | tee "$WORK/browser1.txt"
  local full_bytes
  full_bytes=$(exec 3<>/dev/tcp/127.0.0.1/$HTTP_PORT; printf 'GET /state.json HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n' >&3;
               cat <&3 | sed '1,/^\r$/d' | wc -c)
  kill -TERM $browser; wait $browser 2>/dev/null || true
  kill -INT $viewer; wait $viewer
  local final
  final=$(grep 'final:' "$WORK/viewer.log")
  local mb
  mb=$(sed -E 's/.*sent [0-9]+ messages ([0-9.]+) MB.*/\1/' <<<"$final")
  local messages wire
  messages=$(sed -E 's/.*sent ([0-9]+) messages.*/\1/' <<<"$final")
  wire=$(sed -E 's/.*\(([0-9.]+) MB on the wire\).*/\1/' <<<"$final")
  field() { grep -o "\"$1\": *[^,}]*" "$WORK/state1.json" | head -n 1 | sed 's/.*: *//'; }
  echo
  echo "viewer_load: $ROBOTS robots, ${DURATION_S} s, server outputs replayed at 1x in $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }') s"
  awk -v a="$t0" -v b="$t1" -v c0="$ticks0" -v c1="$ticks1" -v hz="$(getconf CLK_TCK)" \
    'BEGIN { printf "  viewer CPU            %.1f %% of one core (%.2f s CPU)\n", 100 * (c1 - c0) / hz / (b - a), (c1 - c0) / hz }'
  awk -v a="$t0" -v b="$t1" -v mb="$mb" -v n="$messages" -v wire="$wire" -v full="$full_bytes" \
    'BEGIN { printf "  WebSocket to 1 page   %.1f kB/s on the wire (permessage-deflate; TCP bytes acked), %.1f kB/s of JSON (%s MB in %s messages, incl. the first full state); the final full state: %.2f MB of JSON\n", 1000 * wire / (b - a), 1000 * mb / (b - a), mb, n, full / 1e6 }'
  echo "  page frame time       $(sed -n 's/.*draw() with everything[^:]*: //p' "$WORK/browser1.txt") at the end, one per animation frame (performance.now() around draw())"
  echo "                        during the replay: mean $(field mean_frame_ms) ms, max $(field max_frame_ms) ms over $(field frames) frames"
  echo "  page holds            $(grep -c '"key"' "$WORK/state1.json") trajectories, $(field tiles) tiles, $(field encounters) encounters, map update $(field map_update)"
  echo "  viewer final          ${final#*final: }"
  echo "  files in $WORK (load.png: the page at the end)"
}
export -f measure
export BIN URL HTTP_PORT CHROMIUM WORK ROBOTS DURATION_S
"$ROOT/scripts/netns-run.sh" bash -c measure
