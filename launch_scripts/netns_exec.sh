#!/usr/bin/env bash
# Runs a command inside a private network namespace with only loopback, multicast routed to it,
# so DDS discovery works and no packet leaves the host (or reaches another test run).
# Usage: launch_scripts/netns_exec.sh COMMAND [ARGS...]   (needs root, or user namespaces)
set -euo pipefail
# The script runs itself again inside the new namespace, marked by its first argument (not by the
# environment, which a caller could pass on and so configure the host's own interfaces).
marker="--in-private-netns"
if [[ "${1:-}" != "$marker" ]]; then
    if [[ "$(id -u)" -eq 0 ]]; then
        exec unshare --net -- "$0" "$marker" "$@"
    else
        exec unshare --map-root-user --net -- "$0" "$marker" "$@"
    fi
fi
shift
ip link set lo up
ip link set lo multicast on
if ! route="$(ip route add 224.0.0.0/4 dev lo 2>&1)"; then
    [[ "$route" == *"File exists"* ]] || { echo "netns_exec.sh: ip route add 224.0.0.0/4 dev lo: $route" >&2; exit 1; }
fi
exec "$@"
