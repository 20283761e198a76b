//! Command-line front end: argument parsing and dispatch. The numerics live in the library.

mod bench;
mod chart;
mod eval;
mod model_info;
#[cfg(feature = "replay")]
mod replay;
mod simulate;
mod source;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

pub use source::ModelArgs;

/// Rigid-body dynamics of URDF robots.
#[derive(Parser, Debug)]
#[command(name = "spatial_dynamics", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Print the model's coordinates (joints, their types and indices in q and v).
    Model {
        #[command(flatten)]
        model: ModelArgs,
        /// Print JSON: {"nq", "nv", "nbodies", "joints": [{"name", "type", "q_index", "nq", "v_index", "nv"}], "locked_joints", "fused_links", "reduction"}.
        #[arg(long)]
        json: bool,
    },
    /// Answer JSON requests, one per line on stdin, one answer per line on stdout.
    Eval {
        #[command(flatten)]
        model: ModelArgs,
    },
    /// Time each algorithm: nanoseconds per call over many random states (median of repeats).
    Bench {
        #[command(flatten)]
        model: ModelArgs,
        /// Print JSON: {"nv", "ns_per_call": {KERNEL: ns}, "flops_per_call", "gflops", "auto_method" (null, with "auto_method_error", when forward dynamics has no answer), "frame", "instruction_set"}; the kernels are rnea, crba, fd_aba, fd_crba, fd_rnea_columns, gravity, frame_jacobian, center_of_mass, rnea_derivatives and aba_derivatives, and, only when --kernels names them, rnea_rows (ns per state, the states in blocks of 64) and sim_rk4 and sim_semi_implicit_euler (ns per step).
        #[arg(long)]
        json: bool,
        /// Time only these kernels, comma-separated (default: all of them but rnea_rows and the simulation's).
        #[arg(long, value_delimiter = ',', value_name = "NAME,...")]
        kernels: Vec<String>,
        #[command(flatten)]
        settings: bench::Settings,
        #[command(flatten)]
        sim: bench::SimSettings,
    },
    /// Regenerate the README's charts (SVG) and the CSV behind each: timing against nv,
    /// forward-dynamics error against time, integrator work-precision.
    Chart(chart::ChartArgs),
    /// Integrate forward dynamics in time and write the trajectory as CSV.
    Simulate {
        #[command(flatten)]
        model: ModelArgs,
        #[command(flatten)]
        sim: simulate::SimulateArgs,
    },
    /// Run the node's topic computations over a recorded bag (MCAP or sqlite3), offline, into a new MCAP bag.
    #[cfg(feature = "replay")]
    Replay {
        #[command(flatten)]
        model: ModelArgs,
        #[command(flatten)]
        replay: replay::ReplayArgs,
    },
    /// Run the ROS 2 node: `node [--ros-args -r __node:=NAME -r __ns:=/NS --params-file FILE -p NAME:=VALUE]`.
    #[cfg(feature = "node")]
    Node {
        /// ROS arguments, after --ros-args.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

/// Parses the arguments and runs the command.
pub fn run() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Model { model, json } => model_info::run(&model, json),
        Command::Eval { model } => eval::run(&model),
        Command::Bench {
            model,
            json,
            kernels,
            settings,
            sim,
        } => bench::run(&model, json, &kernels, &settings, &sim),
        Command::Chart(args) => chart::run(&args),
        Command::Simulate { model, sim } => simulate::run(&model, &sim),
        #[cfg(feature = "replay")]
        Command::Replay { model, replay } => replay::run(&model, &replay),
        #[cfg(feature = "node")]
        Command::Node { args } => crate::node::run(&args),
    };
    exit_code(result)
}

/// The process's exit status for a command's result; an error is printed to stderr first.
pub fn exit_code(result: Result<(), String>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("spatial_dynamics: {message}");
            ExitCode::FAILURE
        }
    }
}
