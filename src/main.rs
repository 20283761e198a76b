//! The `spatial_dynamics` command: `model`, `eval` (and, later, the ROS 2 node).

#[cfg(feature = "replay")]
mod bag;
mod cli;
#[cfg(feature = "node")]
mod node;

fn main() -> std::process::ExitCode {
    cli::run()
}
