#!/usr/bin/env bash
# Recorder test: anchormap-test-record (the system tests' logger) loses nothing when its
# handler thread stalls during a burst, where lcm-logger (LCM 1.3.1: 30 messages queued per
# subscription between the receive thread and the handlers) may drop. In a private network
# namespace (multicast on loopback only, ttl=0):
#   anchormap-test-record and lcm-logger, both on one CPU, record channel BURST;
#   their main threads (which run the handlers; LCM's receive threads stay as they are) are
#   put in SCHED_IDLE and a busy loop takes that CPU, so the handlers all but stop while
#   the receive threads still read the socket (4 MiB receive buffers: no kernel drop);
#   anchormap-test-publish-burst sends COUNT messages of BYTES bytes at once;
#   the busy loop ends, both catch up and are stopped with SIGINT.
# Assert: the recorder's log holds all COUNT messages and it exited cleanly. Both counts and
# the recorder's longest backlog (messages written back to back, each waiting when the one
# before was done) are printed. When lcm-logger kept every message too, the stall did not
# take (the scheduler's call): skipped, as it proves nothing. Measured: lcm-logger keeps 31
# (its queue: 30, plus one in lcm.c's `<=`) to 36 of 200, the recorder 200.
# Without network namespaces or lcm-logger: exit 77 (ctest SKIP_RETURN_CODE).
#
# usage: record_test.sh BUILD_DIR      (ANCHORMAP_KEEP_TEST_DIR=1 keeps the files)
set -uo pipefail

BUILD=${1:?usage: record_test.sh BUILD_DIR}
BIN=$BUILD/bin
SKIP=77
URL="udpm://239.255.76.67:7667?ttl=0"
COUNT=${COUNT:-200}
BYTES=${BYTES:-10000}

TEST_NAME=record_test
source "$(dirname "$0")/system_test_lib.sh"

# The first CPU this process may run on.
first_cpu() { taskset -cp $$ | sed 's/.*: *//; s/[-,].*//'; }

# threads_at_least PID N: true when process PID runs N threads or more.
threads_at_least() { [ "$(ls /proc/"$1"/task 2>/dev/null | wc -l)" -ge "$2" ]; }

inside_namespace() {
  local work=$1 cpu
  ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || return 3
  cpu=$(first_cpu)
  taskset -c "$cpu" "$BIN/anchormap-test-record" --channels BURST --output "$work/recorder.lcmlog" \
    --lcm-url "$URL" >"$work/recorder.log" 2>&1 &
  local recorder=$!
  # (Debian's lcm-logger 1.3.1 refuses -l although its help lists it: use the variable.)
  LCM_DEFAULT_URL="$(logger_url "$URL")" taskset -c "$cpu" lcm-logger -c BURST \
    -f "$work/lcm_logger.lcmlog" >"$work/lcm_logger.log" 2>&1 &
  local logger=$!
  # Both subscribed (their receive threads up): the recorder says so; lcm-logger runs a
  # writer thread and, once subscribed, LCM's receive thread.
  poll_until 20 grep -q recording "$work/recorder.log" || { log "the recorder never started"; return 1; }
  poll_until 20 threads_at_least "$recorder" 2 || { log "the recorder has no receive thread"; return 1; }
  poll_until 20 threads_at_least "$logger" 3 || { log "lcm-logger never subscribed"; return 1; }
  # A process's first thread (its id is the pid) runs LCM's handlers in both.
  chrt --idle -p 0 "$recorder" && chrt --idle -p 0 "$logger" ||
    { log "cannot give the handler threads SCHED_IDLE"; return $SKIP; }
  taskset -c "$cpu" bash -c 'while :; do :; done' &
  local busy=$!
  sleep 0.2
  "$BIN/anchormap-test-publish-burst" --channel BURST --count "$COUNT" --bytes "$BYTES" \
    --lcm-url "$URL" || { kill "$busy"; log "the publisher failed"; return 1; }
  sleep 0.5
  kill "$busy"; wait "$busy" 2>/dev/null
  # Back to the normal class: beside other tests, an idle-class thread could starve.
  chrt --other -p 0 "$recorder"; chrt --other -p 0 "$logger"
  wait_for_loggers 30 "$recorder" "$logger" || log "the recorders were still behind after 30 s"
  kill -INT "$recorder" "$logger"
  local status=0
  wait "$recorder" || { log "the recorder did not exit cleanly"; status=1; }
  wait "$logger"
  return $status
}

main() {
  require_tools anchormap-test-record anchormap-test-publish-burst anchormap-test-log-events
  require_player_and_netns "the recorder test needs a private network for its multicast bus"
  command -v chrt >/dev/null && command -v taskset >/dev/null ||
    { log "chrt / taskset missing (util-linux): skipped"; exit $SKIP; }
  make_work_dir
  local work=$WORK

  export -f inside_namespace first_cpu threads_at_least
  export BIN URL COUNT BYTES TEST_NAME SKIP
  unshare -n bash -c "inside_namespace '$work'"
  local status=$?
  cat "$work/recorder.log" | sed 's/^/record_test: /'
  [ $status -ne $SKIP ] || exit $SKIP
  [ $status -eq 0 ] || { log "FAIL: the run failed (status $status)"; exit 1; }
  local ours theirs
  ours=$("$BIN/anchormap-test-log-events" --log "$work/recorder.lcmlog" | sed -n 's/^BURST //p')
  theirs=$("$BIN/anchormap-test-log-events" --log "$work/lcm_logger.lcmlog" | sed -n 's/^BURST //p')
  log "of $COUNT messages published at once, anchormap-test-record kept ${ours:-0}, lcm-logger ${theirs:-0}"
  [ "${ours:-0}" -eq "$COUNT" ] || { log "FAIL: the recorder lost $((COUNT - ${ours:-0})) messages"; exit 1; }
  # lcm-logger kept everything: its handler never fell 31 behind, so the stall did not take
  # and the run proves nothing either way.
  [ "${theirs:-0}" -lt "$COUNT" ] || { log "SKIPPED: the handlers never fell behind"; exit $SKIP; }
  log "PASS"
}

main "$@"
