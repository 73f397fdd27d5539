#!/usr/bin/env bash
# Agent restart test (issue 13): a robot's agent SIGKILLed in mid-run and started again
# gets a new trajectory, which is anchored at its next encounter, and nothing of the old
# trajectory is lost. In a private network namespace (multicast on loopback only, ttl=0):
#   anchormap-sim (3 robots, 60 s) -> sim.lcmlog
#   lcm-logplayer -> 3 x anchormap-agent, anchormap-server, one bus
#   anchormap-test-record records what the agents published (agents.lcmlog) and the server's outputs
# KILL_AT_S seconds into the replay (data time KILL_AT_S x SPEED = 33 s: after R2's
# encounters with R1 at 19-25 s, before those with R3 at 44-50 s) R2's agent is SIGKILLed
# and started again at once with the same options (its trajectory id is drawn anew). The
# server is paused (SIGSTOP) for the last 2 s of the replay; right after the replay every
# agent gets SIGINT while it holds unacknowledged keyframes, and the server resumes
# (SIGCONT) once every agent has said so: each agent must wait for the server's
# acknowledgements (anchormap-agent --exit-ack-wait-s), say that everything was
# acknowledged, and exit 0. Then the server stops, and its final map is compared with
# anchormap-server --log agents.lcmlog (the same keyframes and encounters, in order):
# the same keyframes and encounters of both R2 trajectories, none missing or doubled,
# poses within 1e-9, no gap bridged, 4 trajectories, all anchored. The agents run with a
# 4 kB outbox memory bound: what waits for an acknowledgement spills to a file (at least
# one keyframe must have).
# Both servers run with the scan-matching sources off (SOURCES, set it to "" for the daemon's
# defaults): the test is about the agents' restart and acknowledgements, and the sources
# would multiply the server's CPU in CI.
# Without network namespaces: exit 77 (ctest SKIP_RETURN_CODE) with a message.
#
# usage: agent_restart_test.sh BUILD_DIR      (ANCHORMAP_KEEP_TEST_DIR=1 keeps the files)
set -uo pipefail

BUILD=${1:?usage: agent_restart_test.sh BUILD_DIR}
BIN=$BUILD/bin
SKIP=77
ROBOTS=3
DURATION_S=60
SPEED=3
KILL_AT_S=${ANCHORMAP_RESTART_KILL_AT_S:-11}
PAUSE_AT_S=7  # after the kill: the server is paused from here until the agents stop
URL="udpm://239.255.76.70:7670?ttl=0"
CONVERGENCE=1e-12
SOURCES=${SOURCES-"--loop-closures false --scan-encounters false"}

TEST_NAME=agent_restart_test
source "$(dirname "$0")/system_test_lib.sh"

start_agent() {
  local work=$1 robot=$2 log=$3
  # A small memory bound: unacknowledged keyframes spill to a file in the work folder and
  # are read back when resent (issue 13: nothing lost while the agent runs).
  "$BIN/anchormap-agent" --robot "$robot" --lcm-url "$URL" --status-period-s 1 \
    --outbox-max-bytes 4096 --outbox-spill-dir "$work" >"$work/$log" 2>&1 &
}

# Resumes the paused server once every agent has said how it stops (waiting for
# acknowledgements, or nothing left to wait for), or after 30 s. A fixed pause raced a loaded
# machine: an agent still working through up to 256 queued scans saw SIGINT only after the
# server had resumed and acknowledged everything, so it never waited.
resume_when_agents_stopping() {
  poll_until 30 every_agent_said "$1" 'waiting up to|everything published was acknowledged|exiting with'
  kill -CONT "$2"
}

inside_namespace() {
  local work=$1
  ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || return 3
  record "$URL" 'ANCHORMAP_KEYFRAMES|ANCHORMAP_ENCOUNTERS' "$work/agents.lcmlog" "$work/logger_agents.log"
  local logger_agents=$!
  record "$URL" 'ANCHORMAP_MAP_HEADER|ANCHORMAP_MAP_CHUNKS|ANCHORMAP_ANCHOR_COVARIANCES|ANCHORMAP_SERVER_STATUS' "$work/out.lcmlog" "$work/logger_out.log"
  local logger_out=$!
  # shellcheck disable=SC2086 # the flags are words
  "$BIN/anchormap-server" --lcm-url "$URL" --status-period-s 1 --convergence-step $CONVERGENCE \
    $SOURCES >"$work/server.log" 2>&1 &
  local server=$!
  local agents=()
  for i in $(seq 1 $ROBOTS); do
    # The killed one's log is kept apart: its last status line never shows an empty outbox.
    local name="agent_R$i.log"
    [ "$i" = 2 ] && name="killed_agent_R2.log"
    start_agent "$work" "R$i" "$name"
    agents+=($!)
  done
  sleep 1
  log "replaying $DURATION_S s of $ROBOTS robots at ${SPEED}x; R2's agent is killed and restarted ${KILL_AT_S} s in"
  LCM_DEFAULT_URL="$URL" lcm-logplayer --speed=$SPEED "$work/sim.lcmlog" >"$work/logplayer.log" 2>&1 &
  local player=$!
  sleep "$KILL_AT_S"
  kill -KILL "${agents[1]}"
  wait "${agents[1]}" 2>/dev/null
  start_agent "$work" R2 agent_R2.log
  agents[1]=$!
  log "R2's agent killed and started again"
  # The server stops answering (SIGSTOP) shortly before the replay ends, so the agents are
  # stopped while holding unacknowledged keyframes: each must wait for the server, which
  # resumes (SIGCONT) when they have said so and acknowledges them.
  sleep "$PAUSE_AT_S"
  kill -STOP "$server"
  wait "$player" || { log "lcm-logplayer failed"; return 1; }
  # Each agent must hold messages the paused server has not acknowledged when it is stopped:
  # on a loaded machine an agent can lag its input by seconds, and stopped before it
  # published anything after the pause it would have nothing to wait for.
  poll_until 15 outboxes_show "$work" '[1-9][0-9]*' ||
    log "an agent still showed an empty outbox 15 s after the replay"
  stop_run --after-agents "resume_when_agents_stopping '$work' $server" --settle 1 "${agents[@]}" -- "$server" \
    -- "$logger_agents" "$logger_out"
}

main() {
  require_tools anchormap-sim anchormap-agent anchormap-server anchormap-test-compare-maps \
    anchormap-test-record
  require_player_and_netns "the agent restart test needs a private network for its multicast bus"
  make_work_dir
  local work=$WORK
  simulate $ROBOTS $DURATION_S

  export -f inside_namespace stop_run start_agent log resume_when_agents_stopping poll_until \
    every_agent_said outboxes_show
  export BIN URL ROBOTS DURATION_S SPEED KILL_AT_S PAUSE_AT_S CONVERGENCE TEST_NAME SOURCES
  unshare -n bash -c "inside_namespace '$work'"
  local status=$?
  recorders_said "$work"
  for f in "$work"/killed_agent_R2.log "$work"/agent_R*.log "$work/server.log"; do
    log "$(basename "$f"): $(grep -E 'final:' "$f" | tail -1 | sed 's/.*final: //' | cut -c1-220)"
  done
  [ $status -eq 0 ] || { log "daemons failed (status $status)"; tail -20 "$work/server.log"; exit 1; }
  local old new
  old=$(grep -o 'trajectory id [0-9]*' "$work/killed_agent_R2.log" | head -1)
  new=$(grep -o 'trajectory id [0-9]*' "$work/agent_R2.log" | head -1)
  log "R2: $old before the kill, $new after"
  [ -n "$old" ] && [ "$old" != "$new" ] || { log "FAIL: the restarted agent kept its trajectory id"; exit 1; }
  local spilled
  spilled=$(cat "$work"/agent_R*.log | grep -o 'final: .*' | grep -oE '\([0-9]+ in all, [0-9]+ read back\)' |
    tr -d '()' | awk '{ s += $1; r += $4 } END { print s + 0, r + 0 }')
  log "keyframes spilled to the outbox files (R1, R3, restarted R2): ${spilled% *} in all, ${spilled#* } read back"
  [ "${spilled% *}" -gt 0 ] || { log "FAIL: no agent spilled past its 4 kB bound"; exit 1; }
  # Every agent waited for the server's acknowledgement of all it published.
  for f in "$work"/agent_R*.log; do
    grep -E 'waiting up to|everything published was acknowledged|exiting with' "$f" | sed "s/^/$TEST_NAME: $(basename "$f"): /"
    grep -q 'waiting up to' "$f" ||
      { log "FAIL: $(basename "$f") did not wait for acknowledgements at its stop"; exit 1; }
    grep -q 'everything published was acknowledged' "$f" ||
      { log "FAIL: $(basename "$f") exited with unacknowledged messages"; exit 1; }
  done

  # shellcheck disable=SC2086
  "$BIN/anchormap-server" --log "$work/agents.lcmlog" --output "$work/reference.lcmlog" $SOURCES \
    --convergence-step $CONVERGENCE --log-level warning >"$work/reference.log" 2>&1 ||
    { log "the reference run failed"; cat "$work/reference.log"; exit 1; }
  "$BIN/anchormap-test-compare-maps" --map "$work/out.lcmlog" --reference "$work/reference.lcmlog" \
    --tolerance 1e-9 --trajectories $((ROBOTS + 1)) ||
    { log "FAIL: the map after R2's restart is not the reference, or a trajectory is not anchored"; exit 1; }
  log "PASS"
}

main "$@"
