#!/usr/bin/env bash
# Plays a rosbag2 bag (MCAP or sqlite3) into the running ROS 2 graph, like `ros2 bag play`:
# recorded pace or --rate, /clock from bag time (--clock HZ, --clock-topics), --loop, --topics,
# --start-offset, --remap. See launch_scripts/play_bag.py --help. Sets up .venv on first use.
# Usage: launch_scripts/play_bag.sh BAG [--clock 100] [--rate 2] [--loop] [--topics /joint_states] ...
# Nodes that should follow the bag's time run with -p use_sim_time:=true.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$repo/launch_scripts/setup_python_env.sh" >/dev/null
exec "$repo/.venv/bin/python" "$repo/launch_scripts/play_bag.py" "$@"
