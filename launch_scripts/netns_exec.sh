#!/usr/bin/env bash
# Runs a command inside a private network namespace with only loopback, multicast routed to it,
# so DDS discovery works and no packet leaves the host (or reaches another test run).
# Usage: launch_scripts/netns_exec.sh COMMAND [ARGS...]   (needs root, or user namespaces)
set -euo pipefail
if [[ "${SD_IN_NETNS:-}" != "1" ]]; then
    if [[ "$(id -u)" -eq 0 ]]; then
        exec env SD_IN_NETNS=1 unshare --net -- "$0" "$@"
    else
        exec env SD_IN_NETNS=1 unshare --map-root-user --net -- "$0" "$@"
    fi
fi
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo 2>/dev/null || true
exec "$@"
