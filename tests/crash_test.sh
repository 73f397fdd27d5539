#!/usr/bin/env bash
# Crash test (issue 13): nothing accepted is lost when the server dies. In a private network
# namespace (multicast on loopback only, ttl=0: nothing leaves the namespace):
#   anchormap-sim (3 robots, 60 s; scan mode 40 s) -> sim.lcmlog
#   lcm-logplayer -> 3 x anchormap-agent, anchormap-server --journal DIR, one bus
#   anchormap-test-record records what the agents published (agents.lcmlog) and the server's outputs
# While the replay runs (30 s; the kills may go on a few seconds longer), the server is SIGKILLed KILLS times, each after a random
# 1.0-4.0 s of life (scan mode 2.0-3.5 s), and restarted with its journal after a random 0-0.7 s down (what the
# agents publish meanwhile is lost and must be resent); seeded: ANCHORMAP_CRASH_SEED,
# printed.
# After the replay the test waits until every agent's outbox is empty (everything
# acknowledged by the last server), stops the daemons (the server ends with a batch step),
# and compares the last server's final map with the uninterrupted reference:
# anchormap-server --log agents.lcmlog (the same keyframes and encounters, in order).
# Assert: the same keyframes and encounters, none missing or doubled, poses within 1e-9
# (both runs iterate their final batch step to a 1e-12 step), no gap bridged, KILLS + 1
# server instance ids seen on the status channel.
# Snapshots: every server writes one each second (and every 100 journal events), so most
# restarts restore the newest snapshot and replay only the journal after it (some kills land
# while one is being written); at least one restart must have used one. Before restart 5
# the newest snapshot is cut short: that restart must refuse it and use the one before it
# (or the whole journal).
# Mode `scan` (ctest crash_scan_test): the scan-matching sources on (loop closures, scan
# encounters; the reference too) with a smaller global-search budget, a 40 s session, lives
# of 2-3.5 s, snapshots as above (since version 2 they hold the smoother's and the
# sources' state), and each server's life counted from when it is up: a restart restores the
# newest snapshot and replays the journal after it, reusing the journaled match results
# (ServerNode::kJournalMatch) instead of matching again; asserted: at least one restart used
# a snapshot, the restarts reused some journaled matches (restart 6 finds no snapshot: the
# whole journal is replayed), none was journaled for another
# match or under other options, both sources accepted something, and the final map is the
# uninterrupted one's as above.
# Every mode but `full` runs the daemons' default reduced pose graph (snapshot format 12: the
# aliases and the folder are in the snapshots; a restart's journal replay runs every update,
# the fold reads the estimate); asserted also: the last server folded keyframes.
# Mode `full` (ctest crash_full_graph_test): every keyframe a variable (`--reduced-graph false`,
# the reference too; no scan source; restarts defer the journal's updates to one batch step),
# seed 4's 40 s, lives of 2-3.5 s from when the server is up; asserted: a restart used a
# snapshot, and the final map is the uninterrupted one's.
# Without network namespaces: exit 77 (ctest SKIP_RETURN_CODE) with a message.
#
# usage: crash_test.sh BUILD_DIR [snapshots|scan|full]   (ANCHORMAP_KEEP_TEST_DIR=1 keeps the files)
set -uo pipefail

BUILD=${1:?usage: crash_test.sh BUILD_DIR [snapshots|scan|full]}
MODE=${2:-snapshots}
DURATION_S=60
SPEED=2
LIFE_MIN_MS=1000
LIFE_SPAN_MS=3000
case $MODE in
  snapshots)
    SOURCES="--loop-closures false --scan-encounters false"
    SNAPSHOTS="--snapshot-every-s 1 --snapshot-every-events 100" ;;
  scan)
    # The global searches (about 0.2 s CPU each) are nearly all of the sources' cost: a
    # team-wide budget of about 20 instead of about 75 (the same for the reference) keeps
    # the test within its time on a loaded 2-core machine; the recovery under test is the
    # same. A shorter session (40 s at 2x). Lives of 2-3.5 s: a restarted server holds what
    # waits for the settle time (2 s) from its restart, so a shorter life adds nothing.
    SOURCES="--loop-closures true --scan-encounters true --scan-global-searches-per-s 0.25 --scan-global-burst 10"
    SNAPSHOTS="--snapshot-every-s 1 --snapshot-every-events 100"
    DURATION_S=40
    # Simulation seed 4: in the office's first 40 s its robots revisit places (9 loop closures
    # and 4 scan encounters offline); seed 1's routes there give no loop-closure candidate.
    SIM_SEED=4
    LIFE_MIN_MS=2000
    LIFE_SPAN_MS=1500 ;;
  full)
    # The full graph (--reduced-graph false): no scan source, seed 4's revisits (which the
    # default would fold), lives counted from when the server is up.
    SOURCES="--loop-closures false --scan-encounters false --reduced-graph false"
    SNAPSHOTS="--snapshot-every-s 1 --snapshot-every-events 100"
    DURATION_S=40
    SIM_SEED=4
    LIFE_MIN_MS=2000
    LIFE_SPAN_MS=1500 ;;
  *) echo "crash_test: mode $MODE is not snapshots, scan or full" >&2; exit 2 ;;
esac
BIN=$BUILD/bin
SKIP=77
ROBOTS=3
KILLS=10
URL="udpm://239.255.76.69:7669?ttl=0"
CONVERGENCE=1e-12
MAX_WAIT_S=60
SEED=${ANCHORMAP_CRASH_SEED:-$(date +%s)}

TEST_NAME=crash_test
source "$(dirname "$0")/system_test_lib.sh"

milliseconds_as_seconds() { printf '%d.%03d' $(($1 / 1000)) $(($1 % 1000)); }

# Starts server number `run`; its pid in the caller's `server`.
start_server() {
  local work=$1 run=$2
  # shellcheck disable=SC2086 # the flags are words
  "$BIN/anchormap-server" --lcm-url "$URL" --journal "$work/journal" --status-period-s 1 \
    $SNAPSHOTS $SOURCES --convergence-step $CONVERGENCE >"$work/server_$run.log" 2>&1 &
  server=$!
}

# Waits (at most 20 s) until server number `run` is on the bus: a background child of a
# script ignores SIGINT until the server installs its handler, so a stop sent earlier
# would be lost.
wait_until_listening() {
  local work=$1 run=$2 i
  for i in $(seq 1 200); do
    grep -q 'listening on' "$work/server_$run.log" 2>/dev/null && return 0
    sleep 0.1
  done
  log "server $run never came up"; return 1
}

inside_namespace() {
  local work=$1
  ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || return 3
  local agents=()
  record "$URL" 'ANCHORMAP_KEYFRAMES|ANCHORMAP_ENCOUNTERS' "$work/agents.lcmlog" "$work/logger_agents.log"
  local logger_agents=$!
  record "$URL" 'ANCHORMAP_MAP_HEADER|ANCHORMAP_MAP_CHUNKS|ANCHORMAP_ANCHOR_COVARIANCES|ANCHORMAP_SERVER_STATUS' "$work/out.lcmlog" "$work/logger_out.log"
  local logger_out=$!
  local run=0
  local server
  start_server "$work" $run
  for i in $(seq 1 $ROBOTS); do
    "$BIN/anchormap-agent" --robot "R$i" --lcm-url "$URL" --status-period-s 1 >"$work/agent_R$i.log" 2>&1 &
    agents+=($!)
  done
  sleep 1
  log "replaying $DURATION_S s of $ROBOTS robots at ${SPEED}x; the server is killed $KILLS times (seed $SEED)"
  LCM_DEFAULT_URL="$URL" lcm-logplayer --speed=$SPEED "$work/sim.lcmlog" >"$work/logplayer.log" 2>&1 &
  local player=$!
  RANDOM=$SEED
  local started=$SECONDS
  while [ $run -lt $KILLS ]; do
    local life_ms=$((LIFE_MIN_MS + RANDOM % LIFE_SPAN_MS)) down_ms=$((RANDOM % 700))
    # Scan mode: a life starts when the server is up (its replay may run matches its
    # predecessor never ran; killed before it is up it would publish no instance id).
    if [ "$MODE" != snapshots ]; then wait_until_listening "$work" $run || return 1; fi
    sleep "$(milliseconds_as_seconds $life_ms)"
    kill -KILL "$server"
    wait "$server" 2>/dev/null
    run=$((run + 1))
    log "kill $run after ${life_ms} ms of life ($((SECONDS - started)) s into the replay), ${down_ms} ms down"
    sleep "$(milliseconds_as_seconds $down_ms)"
    if [ $run -eq 5 ] && [ "$MODE" = snapshots ]; then
      local newest
      newest=$(ls "$work"/journal/snapshot-*.bin 2>/dev/null | tail -1)
      if [ -n "$newest" ]; then
        truncate -s 100 "$newest" && echo "$newest" >"$work/cut_snapshot"
        log "cut $(basename "$newest") short before restart $run"
      fi
    fi
    if [ $run -eq 6 ] && [ "$MODE" = scan ]; then
      # One restart from the whole journal: the journaled matches' reuse is always exercised
      # (the others' tails after a snapshot are short and may hold none).
      rm -f "$work"/journal/snapshot-*.bin
      log "removed the snapshots before restart $run"
    fi
    start_server "$work" $run
  done
  wait "$player" || { log "lcm-logplayer failed"; return 1; }
  wait_until_listening "$work" $run || return 1
  # The agents' status lines (every second) must postdate the last restart.
  sleep 1.5
  wait_for_outboxes "$work" $MAX_WAIT_S
  stop_run "${agents[@]}" -- "$server" -- "$logger_agents" "$logger_out"
}

main() {
  require_tools anchormap-sim anchormap-agent anchormap-server anchormap-test-compare-maps \
    anchormap-test-record
  require_player_and_netns "the crash test needs a private network for its multicast bus"
  make_work_dir
  local work=$WORK
  simulate $ROBOTS $DURATION_S "${SIM_SEED:-1}"

  export -f inside_namespace stop_run outboxes_show outboxes_empty wait_for_outboxes start_server milliseconds_as_seconds \
    wait_until_listening log
  export BIN URL ROBOTS DURATION_S SPEED KILLS CONVERGENCE MAX_WAIT_S SEED TEST_NAME MODE SOURCES \
    LIFE_MIN_MS LIFE_SPAN_MS \
    SNAPSHOTS
  unshare -n bash -c "inside_namespace '$work'"
  local status=$?
  recorders_said "$work"
  for run in $(seq 1 $KILLS); do
    grep -h 'journal .*replayed' "$work/server_$run.log" | sed 's/.*journal [^ ]*: /restart '$run': /; s/; resuming with \(.*keyframes [0-9]* encounters [0-9]*\).*/; \1/; s/^/crash_test: /'
  done
  for f in "$work"/agent_R*.log "$work/server_$KILLS.log"; do
    log "$(basename "$f"): $(grep -E 'final:' "$f" | tail -1 | sed 's/.*final: //')"
  done
  [ $status -eq 0 ] || { log "daemons failed (status $status)"; tail -20 "$work/server_$KILLS.log"; exit 1; }
  # Inputs released after later ones (the order stage's count, journal included): where a
  # live map may part from the canonical one. Said, not asserted (a robot silent past the
  # patience would be one).
  log "late inputs: $(grep -h 'final:' "$work/server_$KILLS.log" | tail -1 | sed -n 's/.* late \([0-9]*\) .*/\1/p')"
  if [ "$MODE" = scan ]; then
    # A match journaled before a crash is never run again (a restart runs only the matches
    # its predecessor had not run: its backlog), and the journaled results fit their jobs.
    local reused mismatched
    reused=$(cat "$work"/server_*.log | sed -n 's/.*scan matches: \([0-9]*\) reused.*/\1/p' | awk '{ s += $1 } END { print s + 0 }')
    mismatched=$(cat "$work"/server_*.log | sed -n 's/.*(\([0-9]*\) journaled for another match).*/\1/p' | awk '{ s += $1 } END { print s + 0 }')
    log "restarts reused ${reused:-0} journaled scan matches, ${mismatched:-0} journaled for another match"
    [ "${reused:-0}" -ge 1 ] || { log "FAIL: no restart reused a journaled scan match"; exit 1; }
    [ "${mismatched:-0}" -eq 0 ] || { log "FAIL: journaled matches did not fit the replay's"; exit 1; }
    local other_options
    other_options=$(cat "$work"/server_*.log | sed -n 's/.*(\([0-9]*\) journaled under other options).*/\1/p' | awk '{ s += $1 } END { print s + 0 }')
    [ "${other_options:-0}" -eq 0 ] || { log "FAIL: $other_options journaled matches had other options"; exit 1; }
    # Both sources joined something (else the test would prove nothing about them).
    local final loop_accepted scan_accepted
    final=$(grep -h 'final:' "$work/server_$KILLS.log" | tail -1)
    loop_accepted=$(echo "$final" | sed -n 's/.*loop: candidates [0-9]* accepted \([0-9]*\).*/\1/p')
    scan_accepted=$(echo "$final" | sed -n 's/.*scan: candidates [0-9]* accepted \([0-9]*\).*/\1/p')
    log "the last server accepted ${loop_accepted:-0} loop closures and ${scan_accepted:-0} scan encounters"
    [ "${loop_accepted:-0}" -ge 1 ] && [ "${scan_accepted:-0}" -ge 1 ] ||
      { log "FAIL: a scan source accepted nothing"; exit 1; }
  fi
  if [ "$MODE" != full ]; then
    # Keyframes folded (else the test would prove nothing about the reduced graph).
    local folded
    folded=$(grep -h 'final:' "$work/server_$KILLS.log" | tail -1 | sed -n 's/.*reduced graph: nodes [0-9]* folded \([0-9]*\) of.*/\1/p')
    log "the last server folded ${folded:-0} keyframes"
    [ "${folded:-0}" -ge 1 ] || { log "FAIL: no keyframe folded"; exit 1; }
  fi
  check_snapshots "$work" || exit 1
  log "snapshots: $(ls -l "$work"/journal/snapshot-*.bin 2>/dev/null | awk '{ printf "%s %s B; ", $9, $5 }' | sed "s|$work/journal/||g")"
  log "journal: $(stat -c %s "$work/journal/journal.lcmlog") bytes"

  # shellcheck disable=SC2086
  "$BIN/anchormap-server" --log "$work/agents.lcmlog" --output "$work/reference.lcmlog" $SOURCES \
    --convergence-step $CONVERGENCE --log-level warning >"$work/reference.log" 2>&1 ||
    { log "the reference run failed"; cat "$work/reference.log"; exit 1; }
  "$BIN/anchormap-test-compare-maps" --map "$work/out.lcmlog" --reference "$work/reference.lcmlog" \
    --tolerance 1e-9 --instances $((KILLS + 1)) ||
    { log "FAIL: the map after $KILLS crashes differs from the uninterrupted one (seed $SEED, $MODE)"; exit 1; }
  log "PASS"
}

# At least one restart restored a snapshot; (snapshots mode) restart 5 refused the one cut
# short.
check_snapshots() {
  local work=$1 restored
  restored=$(grep -l 'restored .*snapshot-' "$work"/server_*.log 2>/dev/null | wc -l)
  log "$restored of $KILLS restarts restored a snapshot; $(cat "$work"/server_*.log | grep -c 'snapshot of ') snapshots written, $(cat "$work"/server_*.log | grep -c ' refused: ') refused"
  [ "$restored" -ge 1 ] || { log "FAIL: no restart went through a snapshot"; return 1; }
  if [ -f "$work/cut_snapshot" ]; then
    grep -q "$(basename "$(cat "$work/cut_snapshot")") refused: snapshot refused: truncated" "$work/server_5.log" ||
      { log "FAIL: restart 5 did not refuse the snapshot cut short"; return 1; }
    log "restart 5 refused the snapshot cut short: $(grep -h 'journal .*replayed' "$work/server_5.log" | sed 's/.*journal [^ ]*: //; s/ (.*//')"
  fi
}

main "$@"
