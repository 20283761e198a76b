#!/usr/bin/env bash
# Demo: the node simulates the embedded 7-DOF arm under gravity (joint damping and friction from
# its URDF), starting bent, publishing joint_states at 100 Hz and /clock. Drive it with
#   ros2 topic pub /spatial_dynamics/commands std_msgs/msg/Float64MultiArray "{data: [0, 20, 0, 5, 0, 0, 0]}"
# Extra ROS arguments are passed on (e.g. -p real_time_factor:=5.0 -p integrator:=rk4).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exec "$repo/launch_scripts/run_node.sh" \
    -p mode:=simulate -p publish_clock:=true -p integrator:=semi_implicit_euler -p sim_dt:=0.001 \
    -p "passive:=[damping, friction, position_limits]" -p "initial_positions:=[joint2=0.8, joint4=-1.2]" "$@"
