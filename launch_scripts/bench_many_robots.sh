#!/usr/bin/env bash
# How many simulated robots this machine runs in real time at 1 kHz: benches/many_robots.py
# starts N `spatial_dynamics node` processes in simulate mode (sim_dt 1 ms, publish_rate 1000),
# each in its own namespace and ROS_DOMAIN_ID, inside a private network namespace (loopback
# only), and reports the largest N with no missed step on /diagnostics, with the CPU per
# robot. Node logs go to target/bench-many-robots/.
#
# Usage: launch_scripts/bench_many_robots.sh [MODEL OPTIONS] [NAME:=VALUE ...]
#   the model of every robot (default: the embedded 7-DOF arm), by the options of
#   `spatial_dynamics model` that the node has parameters for (--urdf FILE, --builtin NAME of a
#   file in config/models/, --floating-base, --ignore-mimic, --lock NAME=VALUE, --root LINK,
#   --tip LINK, --prune-massless, --gravity X,Y,Z), and node parameters for every robot
#   (docs/node.md), e.g. method:=crba
#   Environment: DURATION (10 s per N), MAX_ROBOTS (64), INTEGRATOR (rk4),
#   SKIP_BUILD=1 uses our binary as it is, PYTHON (the repository's .venv/bin/python: rclpy).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
python="${PYTHON:-$repo/.venv/bin/python}"
bin="$repo/target/release/spatial_dynamics"
[[ -x "$python" ]] || { echo "bench_many_robots.sh: no $python (launch_scripts/setup_python_env.sh, or PYTHON=...)" >&2; exit 1; }
if [[ "${SKIP_BUILD:-0}" != 1 ]]; then
    (cd "$repo" && cargo build --release --quiet)
fi
exec "$repo/launch_scripts/netns_exec.sh" "$python" "$repo/benches/many_robots.py" --bin "$bin" \
    --duration "${DURATION:-10}" --max-robots "${MAX_ROBOTS:-64}" \
    --integrator "${INTEGRATOR:-rk4}" --log-dir "$repo/target/bench-many-robots" "$@"
