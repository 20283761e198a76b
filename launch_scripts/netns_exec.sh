#!/usr/bin/env bash
# Runs a command in a private network namespace with only the loopback, multicast-enabled,
# so DDS discovery works and no packet leaves the host (or reaches another test run).
# Usage: launch_scripts/netns_exec.sh COMMAND [ARGS...]   (needs root, or user namespaces)
set -euo pipefail
usage="usage: launch_scripts/netns_exec.sh COMMAND [ARGS...]"
[[ $# -gt 0 ]] || { echo "netns_exec.sh: $usage" >&2; exit 2; }
# The script runs itself again inside the new namespace, marked by its first two arguments: the
# marker and the caller's namespace. The inner run sets up the loopback only when its namespace is
# not that one, so neither the environment nor a marker given by hand configures the caller's own.
marker="--in-private-netns"
if [[ "$1" != "$marker" ]]; then
    outer="$(readlink /proc/self/ns/net)"
    if [[ "$(id -u)" -eq 0 ]]; then
        exec unshare --net -- "$0" "$marker" "$outer" "$@"
    else
        exec unshare --map-root-user --net -- "$0" "$marker" "$outer" "$@"
    fi
fi
if [[ $# -lt 3 || "$(readlink /proc/self/ns/net)" == "$2" ]]; then
    echo "netns_exec.sh: $marker is this script's own re-entry marker, not a command ($usage)" >&2
    exit 2
fi
shift 2
ip link set lo up
ip link set lo multicast on
# A fresh namespace has no such route; "File exists" is the one failure that leaves it in place.
if ! route="$(ip route add 224.0.0.0/4 dev lo 2>&1)"; then
    [[ "$route" == *"File exists"* ]] || { echo "netns_exec.sh: ip route add 224.0.0.0/4 dev lo: $route" >&2; exit 1; }
fi
exec "$@"
