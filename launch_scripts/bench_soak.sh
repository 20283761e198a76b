#!/usr/bin/env bash
# Soak benchmark of the node over DDS (not a test): joint_states at 1 kHz and 10 kHz (60 s each by
# default) while several clients call the dynamics services; counts inputs, outputs and drops (by the
# node, and datagrams the kernel dropped on its sockets; the rest of a shortfall is lost in DDS),
# input → output latency by stamp, service round trips, and the node's RSS (start, max, end, and
# sampled every 0.5 s). `--quick` is the DDS suite's short run (5 kHz for 8 s).
# Runs inside a private network namespace (loopback only). Prints markdown tables.
# Usage: launch_scripts/bench_soak.sh [--quick] [--rates 1000 10000] [--duration 60] [--clients 3]
#                                     [--service-rate 100] [--json FILE]
# Exit status 3 when anything was lost at 1 kHz or below.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cargo build --release --locked --quiet --manifest-path "$repo/Cargo.toml"
"$repo/launch_scripts/setup_python_env.sh" >/dev/null
export SPATIAL_DYNAMICS_BIN="${SPATIAL_DYNAMICS_BIN:-$repo/target/release/spatial_dynamics}"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-78}"
exec "$repo/launch_scripts/netns_exec.sh" "$repo/.venv/bin/python" "$repo/benches/soak.py" "$@"
