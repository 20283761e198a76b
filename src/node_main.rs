//! The `spatial_dynamics_node` executable: the ROS 2 node alone, for `ros2 run spatial_dynamics
//! spatial_dynamics_node [--ros-args …]` and launch files (the same as `spatial_dynamics node`).

fn main() -> std::process::ExitCode {
    spatial_dynamics::node_main()
}
