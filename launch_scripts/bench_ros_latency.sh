#!/usr/bin/env bash
# Latency benchmark of the node over DDS (not a test): service round trip and topic in → out
# for the 7-DOF default arm, against an rclpy echo node measured in the same run, inside a
# private network namespace. Prints a markdown table. BENCH_CALLS=N sets the sample count.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cargo build --release --locked --quiet --manifest-path "$repo/Cargo.toml"
"$repo/launch_scripts/setup_python_env.sh" >/dev/null
export SPATIAL_DYNAMICS_BIN="${SPATIAL_DYNAMICS_BIN:-$repo/target/release/spatial_dynamics}"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-77}"
exec "$repo/launch_scripts/netns_exec.sh" "$repo/.venv/bin/python" "$repo/benches/ros_latency.py"
