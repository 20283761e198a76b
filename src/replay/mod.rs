//! Offline replay (`spatial_dynamics replay`): the node's topic computations over a recorded bag.
//!
//! Reads every `sensor_msgs/JointState` on `joint_states` and every command on the node's
//! `~/effort_command` (sensor_msgs/JointState, by name) and `~/commands`
//! (std_msgs/Float64MultiArray, in `command_joints` order) from a rosbag2 bag (MCAP or sqlite3;
//! no DDS), and writes a new MCAP bag with, for each valid joint state, what the node would
//! publish:
//!
//! - `~/gravity_effort` (sensor_msgs/JointState): `g(q)`;
//! - `~/acceleration` (spatial_dynamics_msgs/JointDynamics): `q̈ = FD(q, q̇, τ_cmd)` under the
//!   latest command of either kind before it in the bag (zero before the first), as the node
//!   does;
//! - `~/measured_dynamics` (spatial_dynamics_msgs/JointDynamics, a topic of the replay only):
//!   `q`, `q̇` as measured, `q̈` estimated by finite differences of the measured velocities
//!   ([`velocity_derivative`](crate::joint_states::differences::velocity_derivative)), and `τ = RNEA(q, q̇, q̈)`, the efforts that explain the motion;
//! - `~/effort_residual` (sensor_msgs/JointState), for a joint state that carries `effort[]`:
//!   `q`, `q̇` as measured and `effort = τ_measured − RNEA(q, q̇, q̈)`
//!   ([`effort_residual`](crate::joint_states::residual::effort_residual)), what the model does
//!   not explain (the node publishes it one joint state late; replay writes it at the joint
//!   state's own log time).
//!
//! Output stamps are the input's header stamps, log times the input's log times. Joints are
//! matched by name with the node's rules ([`JointMap`]), commands held as the node holds them
//! ([`Commands`]), and the three outputs computed by the node's own code
//! ([`JointStateDynamics`]); a bad message (unreadable, unknown or missing joint, wrong
//! length, non-finite value) is skipped and counted, never fatal.
//!
//! Pieces: [`decode`] (bag order → blocks of samples), [`compute`] (a block's dynamics into one
//! MCAP chunk), [`pipeline`] (the reading, computing and writing threads), [`progress`] (the
//! line on a terminal while it runs), [`report`] (the counts at the end).

use crate::bag::{self, cdr, Bag, Flow, McapWriter, Wanted};
use crate::joint_states::commands::Commands;
use crate::joint_states::joint_map::JointMap;
use crate::output_file::{same_file, PartialFile};
use crate::ros::names::NameResolver;
use clap::ValueEnum;
use decode::Decoder;
use pipeline::pipeline;
use progress::Progress;
use report::report;
use spatial_dynamics_core::error::name_list;
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::{urdf, ForwardDynamicsMethod, Model, ModelOptions};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

mod block;
mod compute;
mod decode;
mod pipeline;
mod problems;
mod progress;
mod report;

const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
const JOINT_DYNAMICS: &str = "spatial_dynamics_msgs/msg/JointDynamics";
const STRING: &str = "std_msgs/msg/String";
const FLOAT64_MULTI_ARRAY: &str = "std_msgs/msg/Float64MultiArray";
/// Output topics, relative to the node's name, in the order each sample writes them.
const OUTPUTS: [(&str, &str); 4] = [
    ("gravity_effort", JOINT_STATE),
    ("acceleration", JOINT_DYNAMICS),
    ("measured_dynamics", JOINT_DYNAMICS),
    ("effort_residual", JOINT_STATE),
];

/// What to replay, and how.
#[derive(Clone, Debug)]
pub struct Config {
    /// Input bag: a rosbag2 directory (with metadata.yaml) or one .mcap or .db3 file.
    pub bag: PathBuf,
    /// Output MCAP file.
    pub out: PathBuf,
    /// Worker threads (`None`: every core).
    pub jobs: Option<usize>,
    /// The node's fully qualified name; topic names resolve as the node resolves them.
    pub node: String,
    pub joint_states: String,
    /// `None`: `~/effort_command`.
    pub effort_command: Option<String>,
    /// `None`: `~/commands`.
    pub commands: Option<String>,
    /// The order of `~/commands` (empty: every coordinate joint, in model order), as the
    /// node's `command_joints` parameter.
    pub command_joints: Vec<String>,
    pub robot_description: String,
    /// Forward-dynamics method of `~/acceleration`.
    pub method: ForwardDynamicsMethod,
    pub time_source: TimeSource,
    /// Seconds: a longer step starts a new segment of the finite differences.
    pub max_gap: f64,
    pub compression: OutCompression,
    pub zstd_level: i32,
    /// Print a JSON summary on stdout.
    pub json: bool,
}

/// Where the model comes from.
#[derive(Clone, Debug)]
pub enum ModelChoice {
    /// Given by the caller (a file or built-in), with where it came from.
    Given { model: Box<Model>, source: String },
    /// The bag's robot description (else the embedded default arm), built with these options.
    FromBag(ModelOptions),
}

/// Which time the finite differences use.
#[derive(Clone, Copy, Debug, PartialEq, ValueEnum)]
pub enum TimeSource {
    /// `header.stamp` of each JointState (when the state was measured).
    Header,
    /// The bag's log (receive) time.
    Log,
}

/// Output chunk compression.
#[derive(Clone, Copy, Debug, PartialEq, ValueEnum)]
pub enum OutCompression {
    None,
    Zstd,
    Lz4,
}

/// Runs replay as `args` says, reporting on stderr (and stdout with `json`).
pub fn run(model: ModelChoice, args: &Config) -> Result<(), String> {
    let started = Instant::now();
    let names = NameResolver::for_node(&args.node).map_err(|e| format!("--node: {e}"))?;
    let node = names.node();
    if !(args.max_gap.is_finite() && args.max_gap > 0.0) {
        return Err("--max-gap must be a positive number of seconds".into());
    }
    let jobs = match args.jobs {
        Some(0) => return Err("--jobs must be at least 1".into()),
        Some(n) if n > MAX_JOBS => return Err(format!("--jobs must be at most {MAX_JOBS}")),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get().min(MAX_JOBS)),
    };
    let mut js_topic = names.resolve(&args.joint_states);
    let mut cmd_topic = names.resolve(args.effort_command.as_deref().unwrap_or("~/effort_command"));
    let mut commands_topic = names.resolve(args.commands.as_deref().unwrap_or("~/commands"));
    let mut description_topic = names.resolve(&args.robot_description);

    // From here a first SIGINT or SIGTERM stops the run at the next message, and the partial
    // output and temporary copies are removed; a second ends the process at once.
    let interrupted = Interruption::catch()?;
    let bag = Bag::open(&args.bag, &interrupted.flag)?;
    refuse_output_over_input(&args.out, &args.bag, &bag.files)?;
    let topics = bag.topics()?;
    if let Some(topics) = &topics {
        for topic in [
            &mut js_topic,
            &mut cmd_topic,
            &mut commands_topic,
            &mut description_topic,
        ] {
            if let Some(t) = recorded(topics, topic) {
                topic.clone_from(&t.name);
            }
        }
    }
    let total = match &topics {
        Some(topics) => {
            let Some(t) = topics.iter().find(|t| t.name == js_topic) else {
                let names: Vec<&str> = topics.iter().map(|t| t.name.as_str()).collect();
                return Err(format!(
                    "{}: no topic {js_topic} (the bag has: {})",
                    args.bag.display(),
                    name_list(&names, names.len())
                ));
            };
            t.count
        }
        None => None,
    };
    let (model, model_source) = load_model(model, &bag, topics.as_deref(), &description_topic)?;
    let map = JointMap::for_model(&model)?;
    if map.base().is_some() {
        return Err(
            "replay does not support a floating base yet (joint_states carry no base motion)"
                .into(),
        );
    }

    // Written beside the output and renamed over it only when the run succeeds.
    let partial = PartialFile::beside(&args.out).map_err(|e| format!("--out {e}"))?;
    let mut writer = McapWriter::create(
        &partial.path,
        match args.compression {
            OutCompression::None => bag::Compression::None,
            OutCompression::Zstd => bag::Compression::Zstd(args.zstd_level),
            OutCompression::Lz4 => bag::Compression::Lz4,
        },
    )?;
    let out_topics: Vec<String> = OUTPUTS.iter().map(|(n, _)| format!("{node}/{n}")).collect();
    let mut channels = [0u16; 4];
    for (k, (_, type_name)) in OUTPUTS.iter().enumerate() {
        let definition = if *type_name == JOINT_STATE {
            bag::msgdefs::joint_state()
        } else {
            bag::msgdefs::joint_dynamics()
        };
        channels[k] = writer.add_topic(&out_topics[k], type_name, &definition)?;
    }

    let commands = Commands::new(&map, model.nv(), &args.command_joints).map_err(|e| {
        format!(
            "--command-joints: {}",
            e.trim_start_matches("command_joints: ")
        )
    })?;
    let max_gap_ns = (args.max_gap * 1e9).round() as i64;
    let decoder = Decoder::new(&model, map, commands, args.time_source, max_gap_ns);
    let wanted = [
        Wanted {
            topic: &js_topic,
            type_name: JOINT_STATE,
        },
        Wanted {
            topic: &cmd_topic,
            type_name: JOINT_STATE,
        },
        Wanted {
            topic: &commands_topic,
            type_name: FLOAT64_MULTI_ARRAY,
        },
    ];
    let progress = std::io::stderr()
        .is_terminal()
        .then(|| Progress::new(total));
    let outcome = pipeline(
        &interrupted.flag,
        &bag,
        &wanted,
        &model,
        args.method,
        jobs,
        decoder,
        writer,
        channels,
        progress,
    )?;
    let seconds = started.elapsed().as_secs_f64();
    let answered = outcome.written[0] > 0;
    if answered {
        partial.keep_as(&args.out)?;
    }
    report(
        args,
        answered.then_some(args.out.as_path()),
        &model,
        &model_source,
        [&js_topic, &cmd_topic, &commands_topic],
        &out_topics,
        &outcome,
        jobs,
        seconds,
    );
    if let Some(total) = total.filter(|&t| outcome.read[0] < t) {
        eprintln!(
            "spatial_dynamics: warning: the bag lists {total} messages on {js_topic}, {} were \
             read: the rest could not be found in its storage files",
            outcome.read[0]
        );
    }
    if !answered {
        return Err(format!(
            "no joint state was answered ({} read on {js_topic}){}",
            outcome.read[0],
            report::problem_lines(&outcome.problems, "joint_states")
                .iter()
                .fold(String::new(), |text, line| text + "\n" + line)
        ));
    }
    Ok(())
}

/// The most worker threads `--jobs` may ask for.
const MAX_JOBS: usize = 256;

/// SIGINT and SIGTERM caught for the length of a run: the first sets `flag`, which the reading
/// checks before each message; with it set, a second ends the process (exit status 130).
struct Interruption {
    flag: Arc<AtomicBool>,
    handlers: Vec<signal_hook::SigId>,
}

impl Interruption {
    fn catch() -> Result<Interruption, String> {
        let flag = Arc::new(AtomicBool::new(false));
        let mut handlers = Vec::new();
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            // Registered first, so it sees the flag as the earlier signal left it.
            let shutdown =
                signal_hook::flag::register_conditional_shutdown(signal, 130, flag.clone());
            let set = signal_hook::flag::register(signal, flag.clone());
            for id in [shutdown, set] {
                handlers.push(id.map_err(|e| format!("cannot catch signal {signal}: {e}"))?);
            }
        }
        Ok(Interruption { flag, handlers })
    }
}

impl Drop for Interruption {
    fn drop(&mut self) {
        for id in self.handlers.drain(..) {
            signal_hook::low_level::unregister(id);
        }
    }
}

/// Refuses an output that would replace the input (the bag's file, one of its storage files or
/// its metadata.yaml), that is a directory, or that a later read of a bag directory would take
/// for one of its storage files.
fn refuse_output_over_input(out: &Path, bag: &Path, files: &[PathBuf]) -> Result<(), String> {
    if out.is_dir() {
        return Err(format!("--out {}: is a directory", out.display()));
    }
    let metadata = bag.is_dir().then(|| bag.join("metadata.yaml"));
    for input in files.iter().chain(&metadata) {
        if same_file(out, input) {
            return Err(format!(
                "--out {} is the bag's {}: the output would replace the input",
                out.display(),
                input.display()
            ));
        }
    }
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let inside = bag.is_dir() && same_file(parent, bag);
    let storage_name = out
        .extension()
        .is_some_and(|e| e == "mcap" || e == "db3" || e == "zstd");
    if inside && storage_name {
        return Err(format!(
            "--out {} is inside the bag directory {}: the next read of the bag would take it \
             for one of its storage files",
            out.display(),
            bag.display()
        ));
    }
    Ok(())
}

/// A topic as the bag records it ([`bag::same_topic`]).
fn recorded<'t>(topics: &'t [bag::TopicInfo], topic: &str) -> Option<&'t bag::TopicInfo> {
    topics.iter().find(|t| bag::same_topic(&t.name, topic))
}

/// The model: `--urdf` / `--builtin`, else the bag's first robot_description, else the default arm.
fn load_model(
    model: ModelChoice,
    bag: &Bag,
    topics: Option<&[bag::TopicInfo]>,
    description_topic: &str,
) -> Result<(Model, String), String> {
    let options = match model {
        ModelChoice::Given { model, source } => return Ok((*model, source)),
        ModelChoice::FromBag(options) => options,
    };
    let listed = topics.is_none_or(|t| t.iter().any(|t| t.name == description_topic));
    let mut description = None;
    if listed {
        let wanted = [Wanted {
            topic: description_topic,
            type_name: STRING,
        }];
        bag.read(&wanted, &mut |m| {
            let text =
                cdr::parse_string(m.data).map_err(|e| format!("{description_topic}: {e}"))?;
            description = Some(text.to_string());
            Ok(Flow::Stop)
        })?;
    }
    let (text, source) = match &description {
        Some(text) => (text.as_str(), format!("the bag's {description_topic}")),
        None => {
            eprintln!(
                "spatial_dynamics: warning: no {description_topic} in the bag and no --urdf or \
                 --builtin: using the embedded default arm (sd_arm7)"
            );
            (DEFAULT_ARM_URDF, "the embedded default arm".to_string())
        }
    };
    let model = urdf::model_from_str(text, &options)
        .map_err(|e| format!("the robot description from {source}: {e}"))?;
    for warning in model.warnings() {
        eprintln!("spatial_dynamics: warning: {warning}");
    }
    Ok((model, source))
}
