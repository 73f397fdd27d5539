# Shared set-up of the multi-process system tests (tests/*_test.sh), sourced after setting
# TEST_NAME (prefix of log lines) and BIN (the build's bin/ folder).

log() { echo "$TEST_NAME: $*"; }

# Exits 1 naming the first of the given bin/ tools that is not built.
require_tools() {
  local tool
  for tool in "$@"; do
    [ -x "$BIN/$tool" ] || { log "$BIN/$tool is missing"; exit 1; }
  done
}

# Sets WORK to a fresh folder, removed at exit unless ANCHORMAP_KEEP_TEST_DIR=1.
make_work_dir() {
  WORK=$(mktemp -d "${TMPDIR:-/tmp}/anchormap-$TEST_NAME.XXXXXX")
  if [ "${ANCHORMAP_KEEP_TEST_DIR:-0}" = "1" ]; then
    log "files in $WORK"
  else
    trap "rm -rf '$WORK'" EXIT
  fi
}

# simulate ROBOTS DURATION_S [SEED]: the simulator's run (seed 1 unless given) into
# $WORK/sim.lcmlog (its summary in $WORK/sim.txt).
simulate() {
  "$BIN/anchormap-sim" --robots "$1" --seed "${3:-1}" --duration-s "$2" --output "$WORK/sim.lcmlog" \
    >"$WORK/sim.txt" || { log "anchormap-sim failed"; exit 1; }
}

# True when this machine gives us a private network namespace with multicast on loopback.
netns_available() {
  unshare -n sh -c 'ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo' \
    >/dev/null 2>&1
}

# Exits with $SKIP, saying why, unless lcm-logplayer and private network namespaces are
# available; `what` names the test and why it needs its own network.
require_player_and_netns() {
  local what=$1
  command -v lcm-logplayer >/dev/null ||
    { log "lcm-logplayer missing (liblcm-bin): skipped"; exit $SKIP; }
  if ! netns_available; then
    log "SKIPPED: network namespaces are unavailable here (unshare -n refused); $what"
    exit $SKIP
  fi
}

# outboxes_show WORK_DIR COUNT: true when every agent's last status line
# (WORK_DIR/agent_R*.log) shows an outbox of COUNT messages (a grep -E pattern).
outboxes_show() {
  local f
  for f in "$1"/agent_R*.log; do
    grep -E 'outbox [0-9]+ \(' "$f" | tail -1 | grep -qE "outbox ($2) \\(" || return 1
  done
}

# True when every agent's outbox is empty: everything it published was acknowledged.
outboxes_empty() { outboxes_show "$1" 0; }

# True when every agent's log (WORK_DIR/agent_R*.log) has a line matching PATTERN (grep -E).
every_agent_said() {
  local f
  for f in "$1"/agent_R*.log; do
    grep -qE "$2" "$f" || return 1
  done
}

# poll_until MAX_S COMMAND...: runs COMMAND every 0.1 s until it succeeds (returns 0) or
# MAX_S seconds have passed (returns 1).
poll_until() {
  local tries=0 max=$(($1 * 10))
  shift
  until "$@"; do
    [ $tries -lt $max ] || return 1
    sleep 0.1
    tries=$((tries + 1))
  done
}

# wait_for_outboxes WORK_DIR MAX_S: waits until outboxes_empty (a mission ends when the
# server holds everything; agents resend meanwhile), at most MAX_S seconds.
wait_for_outboxes() {
  local waited=0
  until outboxes_empty "$1"; do
    sleep 1
    waited=$((waited + 1))
    if [ $waited -ge "$2" ]; then
      log "agents still hold unacknowledged messages after $2 s"
      return 1
    fi
  done
  log "every agent's outbox empty ${waited} s after the replay"
}

# stop_run [--after-agents CMD] [--settle S] AGENT_PIDS... -- DAEMON_PIDS... -- LOGGER_PIDS...
# The end of a run: every agent gets SIGINT (it stops taking input and waits for the
# server's acknowledgements), CMD runs (e.g. a paused server resumed), and the agents are
# waited for; S seconds later (default 0; the last maps go out) each daemon in turn
# (relay, server: the server admits what waits, ends with a batch step and publishes the
# final map) gets SIGINT and is waited for; then, once they have caught up
# (wait_for_loggers), the loggers. Returns 1, saying
# which, when an agent or daemon did not exit cleanly.
stop_run() {
  local after="" settle=0
  while [ $# -gt 0 ]; do
    case $1 in
      --after-agents) after=$2; shift 2 ;;
      --settle) settle=$2; shift 2 ;;
      *) break ;;
    esac
  done
  local agents=() daemons=() loggers=() pid status=0
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do agents+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do daemons+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  loggers=("$@")
  for pid in "${agents[@]}"; do kill -INT "$pid"; done
  [ -z "$after" ] || eval "$after"
  for pid in "${agents[@]}"; do
    wait "$pid" || { log "an agent (pid $pid) did not exit cleanly"; status=1; }
  done
  sleep "$settle"
  for pid in "${daemons[@]}"; do
    kill -INT "$pid"; wait "$pid" || { log "a daemon (pid $pid) did not exit cleanly"; status=1; }
  done
  if [ ${#loggers[@]} -gt 0 ]; then
    wait_for_loggers 30 "${loggers[@]}" || log "the loggers were still behind after 30 s"
    kill -INT "${loggers[@]}"; wait "${loggers[@]}"
  fi
  return $status
}

# udp_bytes_unread: the bytes waiting in this network namespace's UDP sockets (/proc/net/udp's
# rx_queue, hex), i.e. datagrams the kernel has delivered but no reader has taken yet.
udp_bytes_unread() {
  local sum=0 queues
  while read -r _ _ _ _ queues _; do
    [[ $queues == *:* ]] && sum=$((sum + 16#${queues#*:}))
  done < <(tail -n +2 /proc/net/udp)
  echo $sum
}

# lcmlog_sizes PIDS...: the sizes of the .lcmlog files the given processes hold open.
lcmlog_sizes() {
  local pid fd
  for pid in "$@"; do
    for fd in /proc/"$pid"/fd/*; do
      fd=$(readlink "$fd" 2>/dev/null) || continue
      case $fd in *.lcmlog) stat -c %s "$fd" ;; esac
    done
  done | tr '\n' ' '
}

# wait_for_loggers MAX_S LOGGER_PIDS...: waits until the loggers have read every datagram
# sent to them (no UDP socket in the namespace holds unread bytes) and their files have not
# grown for 0.5 s (anchormap-test-record flushes whenever nothing waits, lcm-logger every
# 0.1 s); false after MAX_S s. On a starved
# machine a logger can be seconds behind the daemon it records, and a logger stopped early
# loses the final map the daemon published as it exited.
wait_for_loggers() {
  local max=$1 quiet=0 last=""
  shift
  poll_until "$max" loggers_quiet_for_half_a_second "$@"
}

# One look of wait_for_loggers (bash's locals are seen by the functions a function calls: it
# counts in the caller's `quiet` and `last`): true at the fifth look in a row, 0.1 s apart,
# that finds no unread datagram and the loggers' files as large as at the look before.
loggers_quiet_for_half_a_second() {
  local sizes
  sizes=$(lcmlog_sizes "$@")
  if [ "$(udp_bytes_unread)" -eq 0 ] && [ "$sizes" = "$last" ]; then
    quiet=$((quiet + 1))
  else
    quiet=0
  fi
  last=$sizes
  [ $quiet -ge 5 ]
}

# record URL CHANNELS OUTPUT LOG: anchormap-test-record in the background ($! is its pid)
# recording CHANNELS (an LCM regular expression) on URL into OUTPUT, its lines into LOG.
# Not lcm-logger: LCM 1.3.1 queues at most 30 messages per subscription between a logger's
# receive thread and its handler, and a server's final map is a burst of ~75 (grid tiles and
# map chunks); a logger lagging on a loaded machine dropped part of it (crash_test: the log's
# last map 269 of 272 keyframes). The recorder's queue is unbounded and its receive buffer
# 4 MiB (tests/lcm_recorder.h; record_test.sh shows the difference).
record() {
  "$BIN/anchormap-test-record" --lcm-url "$1" --channels "$2" --output "$3" >"$4" 2>&1 &
}

# recorders_said WORK_DIR: each recorder's closing line (WORK_DIR/logger*.log: what it wrote
# per channel, its longest backlog, the kernel's drops on its socket), for a failure's reader.
recorders_said() {
  local f
  for f in "$1"/logger*.log; do
    [ -f "$f" ] && log "$(basename "$f"): $(grep 'recorded' "$f" | tail -1 | sed 's/^anchormap-test-record: //')"
  done
}

# logger_url URL: URL (which has a query: ?ttl=0) for an lcm-logger, with a 4 MiB receive
# buffer (the kernel caps it at net.core.rmem_max). A server publishes its final map in one
# burst as it exits, beside ~1 MB of grid tiles that reach every socket on the bus (LCM
# filters channels in the process); with the kernel's default buffer (208 KiB) a logger
# starved on a loaded machine lost part of it (crash_test under a load of 8-13: the log's
# last map 269 of the server's 272 keyframes), and the test compared an older map.
logger_url() { echo "$1&recv_buf_size=4194304"; }

# The functions a test's namespace body (run by `bash -c`) calls.
export -f log record logger_url poll_until stop_run outboxes_show outboxes_empty every_agent_said wait_for_outboxes \
  udp_bytes_unread lcmlog_sizes wait_for_loggers loggers_quiet_for_half_a_second
