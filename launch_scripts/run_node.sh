#!/usr/bin/env bash
# Runs the spatial_dynamics ROS 2 node (builds it first if needed).
# Usage: launch_scripts/run_node.sh [CONFIG.yaml] [extra ROS args, e.g. -p method:=crba -r __ns:=/robot1]
# With no arguments it serves the embedded default arm (sd_arm7) as /spatial_dynamics.
# Honours ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and ROS_LOCALHOST_ONLY=1.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="$repo/target/release/spatial_dynamics"
# A first build compiles every dependency: say so, not minutes of silence. Later runs rebuild
# what changed (cargo lists it) or nothing.
if [[ ! -x "$bin" ]]; then
    echo "run_node.sh: building spatial_dynamics (release) on first use: about 3-5 minutes on 2 cores, less with more" >&2
fi
cargo build --release --locked --manifest-path "$repo/Cargo.toml"
args=()
if [[ $# -gt 0 && "$1" == *.yaml ]]; then
    args+=(--params-file "$1")
    shift
fi
exec "$bin" node --ros-args "${args[@]}" "$@"
