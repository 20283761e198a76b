//! The program behind the package's two executables: `spatial_dynamics` (the command line,
//! `src/main.rs`) and `spatial_dynamics_node` (the ROS 2 node alone, `src/node_main.rs`, the
//! executable `ros2 run` and launch files start). Not a library to build on: that is
//! `spatial_dynamics_core`. The modules stay private; only the two entry points are public.

#![forbid(unsafe_code)]

#[cfg(feature = "replay")]
mod bag;
mod cli;
#[cfg(any(feature = "node", feature = "replay"))]
mod joint_states;
#[cfg(feature = "node")]
mod node;
mod output_file;
#[cfg(feature = "replay")]
mod replay;
#[cfg(any(feature = "node", feature = "replay"))]
mod ros;

use std::process::ExitCode;

/// `spatial_dynamics COMMAND …`: parses the command line and runs the command.
pub fn cli_main() -> ExitCode {
    cli::run()
}

/// `spatial_dynamics_node [--ros-args …]`: runs the node with the arguments given, read exactly
/// as `spatial_dynamics node [--ros-args …]` reads them; with none it serves the embedded
/// default arm as `/spatial_dynamics`.
#[cfg(feature = "node")]
pub fn node_main() -> ExitCode {
    let args: Result<Vec<String>, _> = std::env::args_os()
        .skip(1)
        .map(|a| a.into_string())
        .collect();
    let result = match args {
        Ok(args) => node::run(&args),
        Err(arg) => Err(format!("argument {arg:?} is not valid UTF-8")),
    };
    cli::exit_code(result)
}

/// Without the `node` feature there is no node to run: says so and fails.
#[cfg(not(feature = "node"))]
pub fn node_main() -> ExitCode {
    eprintln!(
        "spatial_dynamics_node: built without the `node` feature (cargo build --features node)"
    );
    ExitCode::FAILURE
}
