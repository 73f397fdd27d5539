#!/usr/bin/env bash
# Multi-process integration test (issue 3). In a private network namespace (multicast on
# loopback only, ttl=0: nothing leaves the namespace):
#   anchormap-sim (3 robots, direct encounters) -> sim.lcmlog
#   lcm-logplayer --speed 5 -> 3 x anchormap-agent -> anchormap-server -> anchormap-test-record
# then anchormap-test-check-server-output reads the recording: every robot anchored after
# (never before) its first encounter, merged keyframes within the bounds below of ground
# truth after a rigid fit, anchor covariances published, not growing, and not rising at
# any update that adds encounters; and this script checks that no keyframe was lost on
# the bus and that every daemon exits 0 on SIGINT.
# The server runs with the scan-matching sources off (SOURCES, set it to "" for the daemon's
# defaults): the test is about the daemons on a bus, and CI's time does not allow them
# (measured on a loaded 2-core machine: 19.5 s wall, 15.5 s CPU off; 47.3 s wall, 34.4 s CPU
# on, the server behind the 5x replay until its end; both pass, RMSE 0.022 and 0.005 m).
# Without network namespaces: the same checks on agents + server in one process over
# memq:// (anchormap-replay), then exit 77 (ctest SKIP_RETURN_CODE) since the
# multi-process part did not run.
#
# usage: multiprocess_test.sh BUILD_DIR      (ANCHORMAP_KEEP_TEST_DIR=1 keeps the files)
set -uo pipefail

BUILD=${1:?usage: multiprocess_test.sh BUILD_DIR}
BIN=$BUILD/bin
SKIP=77
ROBOTS=3
DURATION_S=60
SPEED=5
MAX_WAIT_S=120
URL="udpm://239.255.76.67:7667?ttl=0"
# Stated bounds: odometry-only trajectories (no loop closures) drift; 60 s of the sim's
# default odometry noise leaves about 0.4 m RMSE after alignment (seed 1: 0.39 m, max 1.1 m).
MAX_RMSE_M=0.8
MAX_ERROR_M=2.0
SOURCES=${SOURCES-"--loop-closures false --scan-encounters false"}

TEST_NAME=multiprocess_test
source "$(dirname "$0")/system_test_lib.sh"


inside_namespace() {
  local work=$1
  ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || return 3
  local pids=() status=0
  record "$URL" 'ANCHORMAP_.*' "$work/out.lcmlog" "$work/logger.log"
  local logger=$!
  # shellcheck disable=SC2086 # the flags are words
  "$BIN/anchormap-server" --lcm-url "$URL" --status-period-s 2 $SOURCES >"$work/server.log" 2>&1 &
  local server=$!
  for i in $(seq 1 $ROBOTS); do
    "$BIN/anchormap-agent" --robot "R$i" --lcm-url "$URL" --status-period-s 1 >"$work/agent_R$i.log" 2>&1 &
    pids+=($!)
  done
  sleep 1
  log "replaying $DURATION_S s of $ROBOTS robots at ${SPEED}x"
  lcm-logplayer --speed=$SPEED -l "$URL" "$work/sim.lcmlog" || { log "lcm-logplayer failed"; return 1; }
  # The server may be behind a 5x replay (scan matching on its loop; more so under ASan):
  # the agents stay up, resending, until it holds everything.
  wait_for_outboxes "$work" $MAX_WAIT_S || status=1
  sleep 2  # rate-limited maps go out
  stop_run "${pids[@]}" -- "$server" -- "$logger" || status=1
  return $status
}

run_checks() {
  local work=$1
  "$BIN/anchormap-test-check-server-output" --map "$work/out.lcmlog" --truth "$work/sim.lcmlog" \
    --min-robots $ROBOTS --max-rmse-m $MAX_RMSE_M --max-error-m $MAX_ERROR_M
}

main() {
  require_tools anchormap-sim anchormap-agent anchormap-server anchormap-replay \
    anchormap-test-check-server-output anchormap-test-record
  make_work_dir
  local work=$WORK
  simulate $ROBOTS $DURATION_S
  cat "$work/sim.txt"

  if ! netns_available; then
    log "network namespaces unavailable: running agents + server in one process over memq:// instead"
    # shellcheck disable=SC2086
    "$BIN/anchormap-replay" --log "$work/sim.lcmlog" --output "$work/out.lcmlog" --log-level warning $SOURCES \
      || { log "anchormap-replay failed"; exit 1; }
    run_checks "$work" || exit 1
    log "in-process fallback passed; the multi-process part was skipped"
    exit $SKIP
  fi

  export -f inside_namespace stop_run outboxes_show outboxes_empty wait_for_outboxes log
  export BIN URL ROBOTS DURATION_S SPEED TEST_NAME MAX_WAIT_S SOURCES
  unshare -n bash -c "inside_namespace '$work'"
  local status=$?
  recorders_said "$work"
  for f in "$work"/agent_R*.log "$work/server.log"; do
    log "$(basename "$f"): $(grep -E 'final:' "$f" | tail -1 | sed 's/.*final: //')"
  done
  [ $status -eq 0 ] || { log "daemons failed (status $status)"; tail -20 "$work/server.log"; exit 1; }

  # Zero keyframes lost: what the agents sent is what the server holds.
  local sent=0 received
  for f in "$work"/agent_R*.log; do
    sent=$((sent + $(grep 'final:' "$f" | sed -E 's/.* scans [0-9]+ keyframes ([0-9]+) .*/\1/')))
  done
  received=$(grep 'final:' "$work/server.log" | sed -E 's/.* anchored [0-9]+ keyframes ([0-9]+) .*/\1/')
  log "keyframes sent $sent, held by the server $received"
  [ "$sent" = "$received" ] || { log "keyframes were lost"; exit 1; }
  # Duplicates are expected: an agent resends what stays unacknowledged (slow builds, e.g.
  # ASan, acknowledge late) and the server recognises and ignores the copies. Any other
  # refusal fails the test.
  rejected=$(grep 'final:' "$work/server.log" | sed -n 's/.*rejected: \([^|;]*\).*/\1/p' |
    tr ' ' '\n' | grep -v '^duplicate_sequence=' | grep -v '^none$' | grep -v '^$' || true)
  [ -z "$rejected" ] || { log "the server rejected inputs: $rejected"; exit 1; }

  run_checks "$work" || exit 1
  log "PASS"
}

main "$@"
