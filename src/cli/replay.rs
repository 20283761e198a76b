//! `spatial_dynamics replay`: its arguments. The replay itself is [`crate::replay`].

use super::ModelArgs;
use crate::replay::{self, Config, ModelChoice, OutCompression, TimeSource};
use clap::Args;
use spatial_dynamics_core::ForwardDynamicsMethod;
use std::path::PathBuf;

/// Arguments of `replay` (besides the model's).
#[derive(Args, Debug, Clone)]
pub struct ReplayArgs {
    /// Input bag: a rosbag2 directory (with metadata.yaml, or without it: its storage files in split order) or one .mcap or .db3 file, either zstd-compressed (.mcap.zstd, .db3.zstd).
    #[arg(long, value_name = "IN")]
    bag: PathBuf,
    /// Output MCAP file (replaced if it exists, once the run succeeds; never the bag itself).
    #[arg(long, value_name = "OUT.mcap")]
    out: PathBuf,
    /// Worker threads for the dynamics, at most 256 (default: every core). Reading and writing
    /// run in two more threads.
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
    /// The node's fully qualified name: outputs go to NODE/gravity_effort, NODE/acceleration,
    /// NODE/measured_dynamics and NODE/effort_residual; relative topic names resolve in its namespace, `~/x` under it.
    #[arg(long, value_name = "NODE", default_value = "/spatial_dynamics")]
    node: String,
    /// Topic of the measured joint states.
    #[arg(long, value_name = "TOPIC", default_value = "/joint_states")]
    joint_states: String,
    /// Topic of the commanded efforts (sensor_msgs/JointState) [default: NODE/effort_command].
    #[arg(long, value_name = "TOPIC")]
    effort_command: Option<String>,
    /// Topic of the commands (std_msgs/Float64MultiArray, one value per --command-joints
    /// entry) [default: NODE/commands].
    #[arg(long, value_name = "TOPIC")]
    commands: Option<String>,
    /// The order of the commands' values, as the node's command_joints parameter: joint names,
    /// comma-separated (default: every coordinate joint, in model order; joints left out get
    /// zero).
    #[arg(long, value_name = "A,B,C", value_delimiter = ',')]
    command_joints: Vec<String>,
    /// Topic of the URDF (std_msgs/String), used when neither --urdf nor --builtin is given.
    #[arg(long, value_name = "TOPIC", default_value = "/robot_description")]
    robot_description: String,
    /// Forward-dynamics method for NODE/acceleration: aba, crba, rnea_columns.
    #[arg(long, default_value = "aba", value_parser = parse_method)]
    method: ForwardDynamicsMethod,
    /// Time base of the finite differences: the messages' header stamps or their log times.
    #[arg(long, value_enum, default_value_t = TimeSource::Header)]
    time_source: TimeSource,
    /// A step between two joint states longer than this (seconds) starts a new segment: no
    /// difference is taken across it.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.1)]
    max_gap: f64,
    /// Chunk compression of the output.
    #[arg(long, value_enum, default_value_t = OutCompression::Zstd)]
    compression: OutCompression,
    /// zstd level of the output chunks: 1 to 19 (smaller and slower upwards; rosbag2 writes 1),
    /// or −1 to −50 (zstd's --fast=N: larger and faster). The default −2 writes about 4 % more
    /// than level 1 at half its compression time.
    #[arg(long, value_name = "LEVEL", default_value_t = -2, allow_negative_numbers = true,
          value_parser = parse_zstd_level)]
    zstd_level: i32,
    /// Print a JSON summary on stdout: {"model", "read", "written", "skipped", "not_estimated", ...}.
    #[arg(long)]
    json: bool,
}

fn parse_zstd_level(s: &str) -> Result<i32, String> {
    match s.parse::<i32>() {
        Ok(level) if (-50..=19).contains(&level) && level != 0 => Ok(level),
        _ => Err(format!("'{s}' is not a zstd level (1 to 19, or -1 to -50)")),
    }
}

fn parse_method(s: &str) -> Result<ForwardDynamicsMethod, String> {
    s.parse()
}

/// Runs `replay`.
pub fn run(model_args: &ModelArgs, args: &ReplayArgs) -> Result<(), String> {
    let model = match (&model_args.urdf, &model_args.builtin) {
        (Some(path), _) => ModelChoice::Given {
            model: Box::new(model_args.load()?),
            source: format!("file {}", path.display()),
        },
        (_, Some(name)) => ModelChoice::Given {
            model: Box::new(model_args.load()?),
            source: format!("built-in {name}"),
        },
        _ => ModelChoice::FromBag(model_args.options()?),
    };
    let args = args.clone();
    let config = Config {
        bag: args.bag,
        out: args.out,
        jobs: args.jobs,
        node: args.node,
        joint_states: args.joint_states,
        effort_command: args.effort_command,
        commands: args.commands,
        command_joints: args.command_joints,
        robot_description: args.robot_description,
        method: args.method,
        time_source: args.time_source,
        max_gap: args.max_gap,
        compression: args.compression,
        zstd_level: args.zstd_level,
        json: args.json,
    };
    replay::run(model, &config)
}
