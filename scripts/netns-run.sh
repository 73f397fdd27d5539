#!/usr/bin/env bash
# Runs a command in a private network namespace whose loopback carries multicast, so that
# LCM traffic (udpm://239.255.76.67:PORT?ttl=0) of tests and demos never meets anybody
# else's, and nobody else's meets ours.
#
#   scripts/netns-run.sh COMMAND [ARGS...]
#
# Tries `unshare -n` (root), then `unshare -rn` (an unprivileged user namespace). Inside,
# it brings lo up, turns multicast on and routes 224.0.0.0/4 to lo. When neither is
# permitted (some containers), it warns and runs COMMAND on the host network: keep the LCM
# URL at ttl=0 (packets then never leave this host) and pick an unusual port; the host then
# needs a multicast route (LCM's advice: `sudo ip route add 224.0.0.0/4 dev lo`).
# COMMAND sees ANCHORMAP_NETNS=1 inside a namespace and ANCHORMAP_NETNS=0 in the fallback.
set -euo pipefail

if [ $# -eq 0 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
  sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'
  [ $# -eq 0 ] && exit 2 || exit 0
fi

# The namespace's setup, then the command (its arguments passed through untouched).
setup='set -e
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo
export ANCHORMAP_NETNS=1
exec "$@"'

if command -v ip >/dev/null 2>&1; then
  for flags in -n -rn; do
    if unshare "$flags" true 2>/dev/null; then
      exec unshare "$flags" -- bash -c "$setup" netns-run "$@"
    fi
  done
fi

echo "netns-run: warning: no private network namespace here (unshare -n and -rn are not" \
     "permitted, or 'ip' is missing); running on the host network - use ttl=0 LCM URLs" >&2
export ANCHORMAP_NETNS=0
exec "$@"
