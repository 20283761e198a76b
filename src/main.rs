//! The `spatial_dynamics` command: `model`, `eval` (and, later, the ROS 2 node).

#[cfg(feature = "replay")]
mod bag;
mod cli;
#[cfg(any(feature = "node", feature = "replay"))]
mod joint_states;
#[cfg(feature = "node")]
mod node;
#[cfg(feature = "replay")]
mod replay;
#[cfg(any(feature = "node", feature = "replay"))]
mod ros;

fn main() -> std::process::ExitCode {
    cli::run()
}
