//! `spatial_dynamics replay`: the node's topic computations, offline, over a recorded bag.
//!
//! Reads every `sensor_msgs/JointState` on `joint_states` and every commanded effort on the
//! node's `~/effort_command` from a rosbag2 bag (MCAP or sqlite3; no DDS), and writes a new MCAP
//! bag with, for each valid joint state, what the node would publish:
//!
//! - `~/gravity_effort` (sensor_msgs/JointState): `g(q)`;
//! - `~/acceleration` (spatial_dynamics_msgs/JointDynamics): `q̈ = FD(q, q̇, τ_cmd)` under the
//!   latest effort command before it in the bag (zero before the first), as the node does;
//! - `~/measured_dynamics` (spatial_dynamics_msgs/JointDynamics, a topic of the replay only):
//!   `q`, `q̇` as measured, `q̈` estimated by finite differences of the measured velocities
//!   ([`velocity_derivative`]), and `τ = RNEA(q, q̇, q̈)`, the efforts that explain the motion.
//!
//! Output stamps are the input's header stamps, log times the input's log times. Joints are
//! matched by name with the node's rules ([`JointMap`]); a bad message (unreadable, unknown or
//! missing joint, wrong length, non-finite value) is skipped and counted, never fatal.
//!
//! The three come from one [`joint_state_outputs`] call per joint state (the joint transforms
//! and velocity pass computed once); when it fails, the separate algorithms find out which
//! outputs to drop.
//!
//! Work is split three ways: the calling thread reads and decodes the bag in order into blocks
//! of samples; `--jobs` workers compute and serialize whole blocks, each with its own
//! [`Workspace`] (no allocation per message); one writer thread writes the blocks in order.

use super::ModelArgs;
use crate::bag::{
    self, cdr, Bag, ChunkBuilder, FinishedChunk, Flow, McapWriter, RawMessage, Wanted,
};
use crate::node::joint_map::{JointMap, Target};
use clap::{Args, ValueEnum};
use serde_json::{json, Value};
use spatial_dynamics_core::algorithms::{
    forward_dynamics, gravity, joint_state_outputs, rnea, JointStateInputs, JointStateOutputs,
};
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::{urdf, Externals, ForwardDynamicsMethod, Model, Workspace};
use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
const JOINT_DYNAMICS: &str = "spatial_dynamics_msgs/msg/JointDynamics";
const STRING: &str = "std_msgs/msg/String";
/// Output topics, relative to the node's name, in the order each sample writes them.
const OUTPUTS: [(&str, &str); 3] = [
    ("gravity_effort", JOINT_STATE),
    ("acceleration", JOINT_DYNAMICS),
    ("measured_dynamics", JOINT_DYNAMICS),
];
/// Samples per block of work: one MCAP chunk of about 1 MB (uncompressed) per block.
const BLOCK: usize = 1024;

/// Arguments of `replay` (besides the model's).
#[derive(Args, Debug, Clone)]
pub struct ReplayArgs {
    /// Input bag: a rosbag2 directory (with metadata.yaml) or one .mcap or .db3 file.
    #[arg(long, value_name = "IN")]
    bag: PathBuf,
    /// Output MCAP file (replaced if it exists).
    #[arg(long, value_name = "OUT.mcap")]
    out: PathBuf,
    /// Worker threads for the dynamics (default: every core). Reading and writing run in two
    /// more threads.
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
    /// The node's fully qualified name: outputs go to NODE/gravity_effort, NODE/acceleration and
    /// NODE/measured_dynamics.
    #[arg(long, value_name = "NODE", default_value = "/spatial_dynamics")]
    node: String,
    /// Topic of the measured joint states.
    #[arg(long, value_name = "TOPIC", default_value = "/joint_states")]
    joint_states: String,
    /// Topic of the commanded efforts (sensor_msgs/JointState) [default: NODE/effort_command].
    #[arg(long, value_name = "TOPIC")]
    effort_command: Option<String>,
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

// ---- the finite-difference scheme ------------------------------------------------------------

/// `q̈_i`, the derivative at `t_i` of the measured velocities, from the neighbours that share a
/// segment with sample `i` (`h_prev = t_i − t_{i−1} > 0`, `h_next = t_{i+1} − t_i > 0`, seconds):
///
/// ```text
/// both:        q̈_i = [h₋² (q̇_{i+1} − q̇_i) + h₊² (q̇_i − q̇_{i−1})] / (h₋ h₊ (h₋ + h₊))
///              (the slope at t_i of the parabola through the three samples; second order,
///               (q̇_{i+1} − q̇_{i−1}) / 2h for equal steps)
/// next only:   q̈_i = (q̇_{i+1} − q̇_i) / h₊      (first sample of a segment; first order)
/// prev only:   q̈_i = (q̇_i − q̇_{i−1}) / h₋      (last sample of a segment; first order)
/// ```
///
/// Returns `false` (and leaves `out` alone) for a sample with neither neighbour.
pub fn velocity_derivative(
    prev: Option<(f64, &[f64])>,
    v: &[f64],
    next: Option<(f64, &[f64])>,
    out: &mut [f64],
) -> bool {
    match (prev, next) {
        (Some((hm, vm)), Some((hp, vp))) => {
            let (wm, wp) = (hp * hp, hm * hm);
            let d = hm * hp * (hm + hp);
            for k in 0..v.len() {
                out[k] = (wp * (vp[k] - v[k]) + wm * (v[k] - vm[k])) / d;
            }
        }
        (None, Some((hp, vp))) => {
            for k in 0..v.len() {
                out[k] = (vp[k] - v[k]) / hp;
            }
        }
        (Some((hm, vm)), None) => {
            for k in 0..v.len() {
                out[k] = (v[k] - vm[k]) / hm;
            }
        }
        (None, None) => return false,
    }
    true
}

// ---- counting what was skipped -----------------------------------------------------------------

/// One kind of problem: how often, and the first occurrence.
#[derive(Clone, Debug)]
struct Problem {
    count: u64,
    first_log_time: u64,
    first: String,
}

/// Problems by (what was affected, kind).
#[derive(Clone, Debug, Default)]
struct Problems {
    by_kind: BTreeMap<(&'static str, &'static str), Problem>,
}

impl Problems {
    fn add(&mut self, what: &'static str, kind: &'static str, log_time: u64, message: String) {
        self.by_kind
            .entry((what, kind))
            .and_modify(|p| p.count += 1)
            .or_insert(Problem {
                count: 1,
                first_log_time: log_time,
                first: message,
            });
    }

    fn merge(&mut self, other: &mut Problems) {
        for (key, p) in std::mem::take(&mut other.by_kind) {
            match self.by_kind.get_mut(&key) {
                Some(mine) => {
                    mine.count += p.count;
                    if p.first_log_time < mine.first_log_time {
                        mine.first_log_time = p.first_log_time;
                        mine.first = p.first;
                    }
                }
                None => {
                    self.by_kind.insert(key, p);
                }
            }
        }
    }

    fn total(&self, what: &str) -> u64 {
        self.by_kind
            .iter()
            .filter(|((w, _), _)| *w == what)
            .map(|(_, p)| p.count)
            .sum()
    }
}

// ---- blocks of samples ----------------------------------------------------------------------

/// A name order seen in the input: the message's names, the coordinates they fill, and the
/// output's `name[]` encoded once.
#[derive(Debug)]
struct Order {
    names: Vec<String>,
    /// `(q index, v index)` of each named coordinate, in the message's order (passive joints left out).
    slots: Vec<(usize, usize)>,
    encoded_names: Vec<u8>,
}

/// Name orders and frame ids seen so far; only grows, shared with the workers.
#[derive(Debug, Default, Clone)]
struct Tables {
    orders: Vec<Arc<Order>>,
    frames: Vec<String>,
}

/// Samples decoded in order, and what the workers made of them. Sample `lo − 1` (if `lo = 1`)
/// and sample `hi` (if `hi < n`) are neighbours from the blocks before and after, there for the
/// finite differences only.
struct Block {
    seq: u64,
    tables: Arc<Tables>,
    /// Number of sample `lo` among all valid joint states (the outputs' sequence numbers).
    base: u64,
    n: usize,
    lo: usize,
    hi: usize,
    log_time: Vec<u64>,
    stamp: Vec<(i32, u32)>,
    /// Time base of the differences, ns.
    t: Vec<i64>,
    frame: Vec<u32>,
    order: Vec<u32>,
    has_velocity: Vec<bool>,
    /// Sample `i` and `i − 1` are one segment: both have velocities, `0 < t_i − t_{i−1} ≤ max gap`.
    joins_prev: Vec<bool>,
    q: Vec<f64>,
    v: Vec<f64>,
    command: Vec<f64>,
    /// The outputs, as one MCAP chunk with its message indexes.
    chunk: FinishedChunk,
    /// Why the chunk could not be made.
    error: Option<String>,
    problems: Problems,
}

impl Block {
    fn new(nq: usize, nv: usize) -> Block {
        let cap = BLOCK + 2;
        Block {
            seq: 0,
            tables: Arc::default(),
            base: 0,
            n: 0,
            lo: 0,
            hi: 0,
            log_time: vec![0; cap],
            stamp: vec![(0, 0); cap],
            t: vec![0; cap],
            frame: vec![0; cap],
            order: vec![0; cap],
            has_velocity: vec![false; cap],
            joins_prev: vec![false; cap],
            q: vec![0.0; cap * nq],
            v: vec![0.0; cap * nv],
            command: vec![0.0; cap * nv],
            chunk: FinishedChunk::default(),
            error: None,
            problems: Problems::default(),
        }
    }

    /// Copies sample `from` of `other` into slot `to`.
    fn copy_sample(&mut self, to: usize, other: &Block, from: usize, nq: usize, nv: usize) {
        self.log_time[to] = other.log_time[from];
        self.stamp[to] = other.stamp[from];
        self.t[to] = other.t[from];
        self.frame[to] = other.frame[from];
        self.order[to] = other.order[from];
        self.has_velocity[to] = other.has_velocity[from];
        self.joins_prev[to] = other.joins_prev[from];
        self.q[to * nq..(to + 1) * nq].copy_from_slice(&other.q[from * nq..(from + 1) * nq]);
        self.v[to * nv..(to + 1) * nv].copy_from_slice(&other.v[from * nv..(from + 1) * nv]);
        self.command[to * nv..(to + 1) * nv]
            .copy_from_slice(&other.command[from * nv..(from + 1) * nv]);
    }
}

// ---- decoding (in order) -----------------------------------------------------------------------

/// Reads joint states and commands into blocks, in bag order.
struct Decoder {
    nq: usize,
    nv: usize,
    map: JointMap,
    command_map: JointMap,
    time_source: TimeSource,
    max_gap_ns: i64,
    ranges: Vec<Range<usize>>,
    names: Vec<String>,
    values: Vec<f64>,
    /// The order `map` last matched (valid while `Some`).
    current_order: Option<u32>,
    current_frame: u32,
    tables: Arc<Tables>,
    /// Latest commanded effort (`v`-sized), zero before the first.
    command: Vec<f64>,
    scratch_command: Vec<f64>,
    /// `(t, has velocity)` of the last sample decoded.
    prev: Option<(i64, bool)>,
    problems: Problems,
    read: [u64; 2],
    /// Joint states decoded so far (valid ones).
    committed: u64,
    last_log_time: u64,
    log_time_backwards: u64,
}

impl Decoder {
    /// A joint state into slot `block.n`; on success the block has one more sample.
    fn joint_state(&mut self, msg: RawMessage<'_>, block: &mut Block) {
        let i = block.n;
        let (nq, nv) = (self.nq, self.nv);
        let view = match cdr::parse_joint_state(msg.data, &mut self.ranges) {
            Ok(v) => v,
            Err(e) => return self.skip("unreadable message", msg.log_time, e),
        };
        let order = match self.order_of(&view) {
            Ok(o) => o,
            Err((kind, e)) => return self.skip(kind, msg.log_time, e),
        };
        view.position.read_into(&mut self.values);
        let q = &mut block.q[i * nq..(i + 1) * nq];
        if let Err(e) = self
            .map
            .scatter("position", &self.values, Target::Position, false, q)
        {
            return self.skip("bad position", msg.log_time, e);
        }
        view.velocity.read_into(&mut self.values);
        let v = &mut block.v[i * nv..(i + 1) * nv];
        if let Err(e) = self
            .map
            .scatter("velocity", &self.values, Target::Rate, true, v)
        {
            return self.skip("bad velocity", msg.log_time, e);
        }
        let has_velocity = !self.values.is_empty();
        let t = match self.time_source {
            TimeSource::Header => i64::from(view.sec) * 1_000_000_000 + i64::from(view.nanosec),
            TimeSource::Log => msg.log_time as i64,
        };
        let joins_prev = match self.prev {
            Some((t_prev, prev_velocity)) => {
                prev_velocity && has_velocity && t > t_prev && t - t_prev <= self.max_gap_ns
            }
            None => false,
        };
        self.prev = Some((t, has_velocity));
        block.frame[i] = self.frame_of(view.frame_id);
        block.order[i] = order;
        block.log_time[i] = msg.log_time;
        block.stamp[i] = (view.sec, view.nanosec);
        block.t[i] = t;
        block.has_velocity[i] = has_velocity;
        block.joins_prev[i] = joins_prev;
        block.command[i * nv..(i + 1) * nv].copy_from_slice(&self.command);
        block.n += 1;
        self.committed += 1;
    }

    fn skip(&mut self, kind: &'static str, log_time: u64, message: String) {
        self.problems.add("joint_states", kind, log_time, message);
    }

    /// The name order of a message, matching the names only when they differ from the last.
    fn order_of(&mut self, view: &cdr::JointStateView<'_>) -> Result<u32, (&'static str, String)> {
        if let Some(id) = self.current_order {
            let known = &self.tables.orders[id as usize].names;
            if known.len() == self.ranges.len()
                && known
                    .iter()
                    .zip(&self.ranges)
                    .all(|(k, r)| k.as_bytes() == view.name_bytes(r))
            {
                return Ok(id);
            }
        }
        self.current_order = None;
        read_names(view, &self.ranges, &mut self.names).map_err(|e| ("bad joint names", e))?;
        self.map
            .match_names(&self.names, "name")
            .map_err(|e| ("bad joint names", e))?;
        let id = match self
            .tables
            .orders
            .iter()
            .position(|o| o.names == self.names)
        {
            Some(id) => id,
            None => {
                let order = Order {
                    names: self.names.clone(),
                    slots: self.map.answer_order().map(|s| self.map.slot(s)).collect(),
                    encoded_names: cdr::encode_strings(&self.map.answer_names()),
                };
                let tables = Arc::make_mut(&mut self.tables);
                tables.orders.push(Arc::new(order));
                tables.orders.len() - 1
            }
        } as u32;
        self.current_order = Some(id);
        Ok(id)
    }

    fn frame_of(&mut self, frame_id: &str) -> u32 {
        let frames = &self.tables.frames;
        if frames.get(self.current_frame as usize).map(String::as_str) != Some(frame_id) {
            self.current_frame = match frames.iter().position(|f| f == frame_id) {
                Some(k) => k as u32,
                None => {
                    let tables = Arc::make_mut(&mut self.tables);
                    tables.frames.push(frame_id.to_string());
                    (tables.frames.len() - 1) as u32
                }
            };
        }
        self.current_frame
    }

    /// An effort command (the node's `set_effort_command`): every coordinate joint named, the
    /// effort for each; it holds until the next one.
    fn effort_command(&mut self, msg: RawMessage<'_>) {
        let result = (|| {
            let view = cdr::parse_joint_state(msg.data, &mut self.ranges)
                .map_err(|e| ("unreadable message", e))?;
            read_names(&view, &self.ranges, &mut self.names).map_err(|e| ("bad joint names", e))?;
            self.command_map
                .match_names(&self.names, "name")
                .map_err(|e| ("bad joint names", e))?;
            view.effort.read_into(&mut self.values);
            self.scratch_command.iter_mut().for_each(|x| *x = 0.0);
            self.command_map
                .scatter(
                    "effort",
                    &self.values,
                    Target::Rate,
                    false,
                    &mut self.scratch_command,
                )
                .map_err(|e| ("bad effort", e))?;
            self.command.copy_from_slice(&self.scratch_command);
            Ok::<(), (&'static str, String)>(())
        })();
        if let Err((kind, e)) = result {
            self.problems.add("effort_command", kind, msg.log_time, e);
        }
    }
}

/// The names of a message into reusable strings (no allocation once they are long enough).
fn read_names(
    view: &cdr::JointStateView<'_>,
    ranges: &[Range<usize>],
    names: &mut Vec<String>,
) -> Result<(), String> {
    names.resize_with(ranges.len(), String::new);
    for (k, (name, r)) in names.iter_mut().zip(ranges).enumerate() {
        let text = std::str::from_utf8(view.name_bytes(r))
            .map_err(|_| format!("name[{k}] is not UTF-8"))?;
        name.clear();
        name.push_str(text);
    }
    Ok(())
}

// ---- computing (in parallel) -------------------------------------------------------------------

/// A worker's scratch: its workspace, `v`-sized buffers and chunk builder.
struct Scratch {
    ws: Workspace,
    builder: ChunkBuilder,
    /// The measured acceleration.
    a: Vec<f64>,
    out: JointStateOutputs,
    one_by_one: OneByOne,
}

/// The dynamics of samples `lo..hi` of a block, serialized into one MCAP chunk; `channels`
/// are the channel ids of the outputs.
fn compute(
    block: &mut Block,
    model: &Model,
    method: ForwardDynamicsMethod,
    channels: [u16; 3],
    s: &mut Scratch,
) -> Result<(), String> {
    let (nq, nv) = (model.nq, model.nv);
    let tables = block.tables.clone();
    for i in block.lo..block.hi {
        let q = &block.q[i * nq..(i + 1) * nq];
        let v = &block.v[i * nv..(i + 1) * nv];
        let command = &block.command[i * nv..(i + 1) * nv];
        let order = &tables.orders[block.order[i] as usize];
        let (sec, nanosec) = block.stamp[i];
        let frame = tables.frames[block.frame[i] as usize].as_str();
        let log_time = block.log_time[i];
        let sequence = (block.base + (i - block.lo) as u64) as u32;
        let rate = |x| at_rates(&order.slots, x);
        // Starts output `k` of this sample: header, names, positions.
        macro_rules! start {
            ($k:expr) => {
                start_message(
                    s.builder.begin_message(channels[$k], sequence, log_time),
                    (sec, nanosec),
                    frame,
                    order,
                    q,
                )
            };
        }

        // The measured acceleration, when the sample has velocities and a neighbour.
        let measured = if !block.has_velocity[i] {
            Err(("no velocities in the message", "velocity[] is empty"))
        } else {
            let neighbour = |j: usize| {
                let h = (block.t[i].abs_diff(block.t[j])) as f64 * 1e-9;
                (h, &block.v[j * nv..(j + 1) * nv])
            };
            let prev = (i > 0 && block.joins_prev[i]).then(|| neighbour(i - 1));
            let next = (i + 1 < block.n && block.joins_prev[i + 1]).then(|| neighbour(i + 1));
            if velocity_derivative(prev, v, next, &mut s.a) {
                Ok(())
            } else {
                Err((
                    "no neighbour in its segment",
                    "an isolated sample: no difference can be taken",
                ))
            }
        };
        let input = JointStateInputs {
            q,
            v,
            effort_command: command,
            measured_acceleration: measured.is_ok().then_some(s.a.as_slice()),
        };
        // All three at once; on an error, one by one to learn which failed.
        let combined = joint_state_outputs(model, &mut s.ws, method, &input, &mut s.out).is_ok();
        let (node_outputs, inverse) = match combined {
            true => (Ok(()), Ok(())),
            false => s.one_by_one.compute(model, method, &input, &mut s.ws),
        };
        let (g, qdd, tau) = match combined {
            true => (
                s.out.gravity(),
                s.out.acceleration(),
                s.out.inverse_dynamics(),
            ),
            false => (
                &s.one_by_one.g[..],
                &s.one_by_one.qdd[..],
                &s.one_by_one.tau[..],
            ),
        };

        // The node's two outputs: both or neither, as the node publishes them.
        match node_outputs {
            Ok(()) => {
                let mut w = start!(0);
                w.f64s(std::iter::empty());
                w.f64s(rate(g));
                s.builder.end_message();
                let mut w = start!(1);
                w.f64s(rate(v));
                w.f64s(rate(qdd));
                w.f64s(rate(command));
                s.builder.end_message();
            }
            Err(e) => block
                .problems
                .add("joint_states", "dynamics failed", log_time, e),
        }

        // Inverse dynamics of the measured motion.
        if let Err((kind, e)) = measured {
            block
                .problems
                .add("measured_dynamics", kind, log_time, e.into());
            continue;
        }
        match inverse {
            Ok(()) => {
                let mut w = start!(2);
                w.f64s(rate(v));
                w.f64s(rate(&s.a));
                w.f64s(rate(tau));
                s.builder.end_message();
            }
            Err(e) => {
                block
                    .problems
                    .add("measured_dynamics", "inverse dynamics failed", log_time, e)
            }
        }
    }
    s.builder.finish(&mut block.chunk)
}

/// The outputs of one sample by the separate algorithms, after the combined call failed: which
/// of them can still be written (the node's two: both or neither).
struct OneByOne {
    g: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
}

impl OneByOne {
    fn compute(
        &mut self,
        model: &Model,
        method: ForwardDynamicsMethod,
        input: &JointStateInputs<'_>,
        ws: &mut Workspace,
    ) -> (Result<(), String>, Result<(), String>) {
        let JointStateInputs { q, v, .. } = *input;
        let node = gravity(model, ws, q)
            .map(|g| self.g.copy_from_slice(g))
            .and_then(|_| {
                let (tau, none) = (input.effort_command, Externals::none());
                forward_dynamics(model, ws, q, v, tau, method, &none)
            })
            .map(|qdd| self.qdd.copy_from_slice(qdd));
        let inverse = match input.measured_acceleration {
            Some(a) => rnea(model, ws, q, v, a).map(|tau| self.tau.copy_from_slice(tau)),
            None => Ok(()),
        };
        (
            node.map_err(|e| e.to_string()),
            inverse.map_err(|e| e.to_string()),
        )
    }
}

/// Header, names and positions: the start of every output.
fn start_message<'b>(
    buf: &'b mut Vec<u8>,
    (sec, nanosec): (i32, u32),
    frame: &str,
    order: &Order,
    q: &[f64],
) -> cdr::Writer<'b> {
    let mut w = cdr::Writer::new(buf);
    w.header(sec, nanosec, frame);
    w.encoded_strings(&order.encoded_names);
    w.f64s(order.slots.iter().map(|&(qi, _)| q[qi]));
    w
}

/// The velocity-like values `x` at the named coordinates, in the message's order.
fn at_rates<'a>(
    slots: &'a [(usize, usize)],
    x: &'a [f64],
) -> impl ExactSizeIterator<Item = f64> + 'a {
    slots.iter().map(move |&(_, vi)| x[vi])
}

// ---- the command -------------------------------------------------------------------------------

/// Fully qualified topic name: `~/x` under the node, `x` under `/`.
fn resolve(name: &str, node: &str) -> String {
    if let Some(rest) = name.strip_prefix("~/") {
        format!("{node}/{rest}")
    } else if name.starts_with('/') {
        name.to_string()
    } else {
        format!("/{name}")
    }
}

/// Runs `replay`.
pub fn run(model_args: &ModelArgs, args: &ReplayArgs) -> Result<(), String> {
    let started = Instant::now();
    let node = resolve(args.node.trim_end_matches('/'), "");
    if node == "/" || node.contains("//") {
        return Err(format!("--node '{}' is not a node name", args.node));
    }
    if !(args.max_gap.is_finite() && args.max_gap > 0.0) {
        return Err("--max-gap must be a positive number of seconds".into());
    }
    let jobs = match args.jobs {
        Some(0) => return Err("--jobs must be at least 1".into()),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let js_topic = resolve(&args.joint_states, &node);
    let cmd_topic = resolve(
        args.effort_command.as_deref().unwrap_or("~/effort_command"),
        &node,
    );
    let description_topic = resolve(&args.robot_description, &node);

    let bag = Bag::open(&args.bag)?;
    let topics = bag.topics()?;
    let total = match &topics {
        Some(topics) => {
            let Some(t) = topics.iter().find(|t| t.name == js_topic) else {
                let names: Vec<&str> = topics.iter().map(|t| t.name.as_str()).collect();
                return Err(format!(
                    "{}: no topic {js_topic} (the bag has: {})",
                    args.bag.display(),
                    names.join(", ")
                ));
            };
            t.count
        }
        None => None,
    };
    let (model, model_source) =
        load_model(model_args, &bag, topics.as_deref(), &description_topic)?;
    let map = JointMap::for_model(&model)?;
    if map.base().is_some() {
        return Err(
            "replay does not support a floating base yet (joint_states carry no base motion)"
                .into(),
        );
    }

    let mut writer = McapWriter::create(
        &args.out,
        match args.compression {
            OutCompression::None => bag::Compression::None,
            OutCompression::Zstd => bag::Compression::Zstd(args.zstd_level),
            OutCompression::Lz4 => bag::Compression::Lz4,
        },
    )?;
    let out_topics: Vec<String> = OUTPUTS.iter().map(|(n, _)| format!("{node}/{n}")).collect();
    let mut channels = [0u16; 3];
    for (k, (_, type_name)) in OUTPUTS.iter().enumerate() {
        let definition = if *type_name == JOINT_STATE {
            bag::msgdefs::joint_state()
        } else {
            bag::msgdefs::joint_dynamics()
        };
        channels[k] = writer.add_topic(&out_topics[k], type_name, &definition)?;
    }

    let decoder = Decoder {
        nq: model.nq,
        nv: model.nv,
        command_map: map.clone(),
        map,
        time_source: args.time_source,
        max_gap_ns: (args.max_gap * 1e9).round() as i64,
        ranges: Vec::new(),
        names: Vec::new(),
        values: Vec::new(),
        current_order: None,
        current_frame: u32::MAX,
        tables: Arc::default(),
        command: vec![0.0; model.nv],
        scratch_command: vec![0.0; model.nv],
        prev: None,
        problems: Problems::default(),
        read: [0; 2],
        committed: 0,
        last_log_time: 0,
        log_time_backwards: 0,
    };
    let wanted = [
        Wanted {
            topic: &js_topic,
            type_name: JOINT_STATE,
        },
        Wanted {
            topic: &cmd_topic,
            type_name: JOINT_STATE,
        },
    ];
    let progress = std::io::stderr()
        .is_terminal()
        .then(|| Progress::new(total));
    let outcome = pipeline(
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
    report(
        args,
        &model,
        &model_source,
        &js_topic,
        &cmd_topic,
        &out_topics,
        &outcome,
        jobs,
        seconds,
    );
    Ok(())
}

/// The model: `--urdf` / `--builtin`, else the bag's first robot_description, else the default arm.
fn load_model(
    model_args: &ModelArgs,
    bag: &Bag,
    topics: Option<&[bag::TopicInfo]>,
    description_topic: &str,
) -> Result<(Model, String), String> {
    if model_args.urdf.is_some() || model_args.builtin.is_some() {
        let source = match (&model_args.urdf, &model_args.builtin) {
            (Some(path), _) => format!("file {}", path.display()),
            (_, Some(name)) => format!("built-in {name}"),
            _ => unreachable!(),
        };
        return Ok((model_args.load()?, source));
    }
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
    let options = model_args.options()?;
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
    for warning in &model.warnings {
        eprintln!("spatial_dynamics: warning: {warning}");
    }
    Ok((model, source))
}

/// What the pipeline counted.
struct Outcome {
    read: [u64; 2],
    written: [u64; 3],
    problems: Problems,
    log_time_backwards: u64,
}

/// Decodes here, computes in `jobs` workers, writes in one writer thread; blocks are recycled.
#[allow(clippy::too_many_arguments)]
fn pipeline(
    bag: &Bag,
    wanted: &[Wanted<'_>],
    model: &Model,
    method: ForwardDynamicsMethod,
    jobs: usize,
    mut decoder: Decoder,
    mut writer: McapWriter,
    channels: [u16; 3],
    mut progress: Option<Progress>,
) -> Result<Outcome, String> {
    let (nq, nv) = (model.nq, model.nv);
    let (work_tx, work_rx) = channel::<Box<Block>>();
    let work_rx = Mutex::new(work_rx);
    let (done_tx, done_rx) = channel::<Box<Block>>();
    let (free_tx, free_rx) = channel::<Box<Block>>();
    // Blocks in flight at most: enough to keep every stage busy, few enough to bound memory.
    let max_blocks = 2 * jobs + 3;
    let builders = (0..jobs)
        .map(|_| writer.chunk_builder())
        .collect::<Result<Vec<_>, _>>()?;

    std::thread::scope(|scope| {
        for builder in builders {
            let (work_rx, done_tx) = (&work_rx, done_tx.clone());
            scope.spawn(move || {
                let mut s = Scratch {
                    ws: Workspace::new(model),
                    builder,
                    a: vec![0.0; nv],
                    out: JointStateOutputs::new(model),
                    one_by_one: OneByOne {
                        g: vec![0.0; nv],
                        qdd: vec![0.0; nv],
                        tau: vec![0.0; nv],
                    },
                };
                loop {
                    let next = work_rx.lock().map(|rx| rx.recv());
                    let Ok(Ok(mut block)) = next else { break };
                    block.error = compute(&mut block, model, method, channels, &mut s).err();
                    if done_tx.send(block).is_err() {
                        break;
                    }
                }
            });
        }
        drop(done_tx);
        let writer_thread = scope.spawn(move || {
            let counts = write_blocks(&mut writer, done_rx, free_tx, channels)?;
            writer.finish()?;
            Ok::<_, String>(counts)
        });

        let mut allocated = 0;
        let mut get_block = |free_rx: &Receiver<Box<Block>>| -> Option<Box<Block>> {
            if let Ok(b) = free_rx.try_recv() {
                return Some(b);
            }
            if allocated < max_blocks {
                allocated += 1;
                return Some(Box::new(Block::new(nq, nv)));
            }
            free_rx.recv().ok()
        };
        let mut seq = 0u64;
        let mut block = get_block(&free_rx).expect("a first block");
        block.n = 0;
        block.lo = 0;
        block.base = 0;
        let mut send =
            |block: Box<Block>, hi: usize, tables: &Arc<Tables>, tx: &Sender<Box<Block>>| {
                let mut block = block;
                block.hi = hi;
                block.seq = seq;
                block.tables = tables.clone();
                seq += 1;
                tx.send(block).is_ok()
            };
        let mut failed = None;
        let result = bag.read(wanted, &mut |m| {
            if m.log_time < decoder.last_log_time {
                decoder.log_time_backwards += 1;
            }
            decoder.last_log_time = m.log_time;
            decoder.read[m.topic] += 1;
            if m.topic == 1 {
                decoder.effort_command(m);
                return Ok(Flow::Continue);
            }
            decoder.joint_state(m, &mut block);
            if let Some(p) = progress.as_mut() {
                p.tick(decoder.read[0]);
            }
            // Full: everything but the newest sample goes out; that one and the one before it
            // (its left neighbour) start the next block.
            if block.n == block.lo + BLOCK + 1 {
                let Some(mut next) = get_block(&free_rx) else {
                    return Ok(Flow::Stop);
                };
                let n = block.n;
                next.copy_sample(0, &block, n - 2, nq, nv);
                next.copy_sample(1, &block, n - 1, nq, nv);
                next.n = 2;
                next.lo = 1;
                next.base = decoder.committed - 1;
                let full = std::mem::replace(&mut block, next);
                if !send(full, n - 1, &decoder.tables, &work_tx) {
                    return Ok(Flow::Stop);
                }
            }
            Ok(Flow::Continue)
        });
        if let Err(e) = result {
            failed = Some(e);
        }
        let n = block.n;
        if n > block.lo {
            send(block, n, &decoder.tables, &work_tx);
        }
        drop(work_tx);
        if let Some(p) = progress.as_mut() {
            p.finish(decoder.read[0]);
        }
        let written = writer_thread
            .join()
            .map_err(|_| "the writer thread panicked".to_string())?;
        if let Some(e) = failed {
            return Err(e);
        }
        let (written, mut problems) = written?;
        decoder.problems.merge(&mut problems);
        Ok(Outcome {
            read: decoder.read,
            written,
            problems: decoder.problems,
            log_time_backwards: decoder.log_time_backwards,
        })
    })
}

/// Writes blocks in sequence order as they come back from the workers.
fn write_blocks(
    writer: &mut McapWriter,
    done: Receiver<Box<Block>>,
    free: Sender<Box<Block>>,
    channels: [u16; 3],
) -> Result<([u64; 3], Problems), String> {
    let mut pending: BTreeMap<u64, Box<Block>> = BTreeMap::new();
    let mut next = 0u64;
    let mut written = [0u64; 3];
    let mut problems = Problems::default();
    for block in done {
        pending.insert(block.seq, block);
        while let Some(mut block) = pending.remove(&next) {
            if let Some(e) = block.error.take() {
                return Err(e);
            }
            writer.write_chunk(&block.chunk)?;
            for (k, &channel) in channels.iter().enumerate() {
                written[k] += block.chunk.count(channel);
            }
            problems.merge(&mut block.problems);
            next += 1;
            // The decoder may have stopped taking blocks; that is fine.
            let _ = free.send(block);
        }
    }
    Ok((written, problems))
}

/// A progress line on stderr (only when it is a terminal), at most ten times a second.
struct Progress {
    total: Option<u64>,
    started: Instant,
    last: Instant,
}

impl Progress {
    fn new(total: Option<u64>) -> Progress {
        let now = Instant::now();
        Progress {
            total,
            started: now,
            last: now,
        }
    }

    fn tick(&mut self, done: u64) {
        if done.is_multiple_of(1024) && self.last.elapsed() >= Duration::from_millis(100) {
            self.last = Instant::now();
            self.draw(done);
        }
    }

    fn draw(&self, done: u64) {
        let rate = done as f64 / self.started.elapsed().as_secs_f64().max(1e-9);
        let line = match self.total {
            Some(total) if total > 0 => {
                let fraction = (done as f64 / total as f64).min(1.0);
                let filled = (fraction * 30.0) as usize;
                format!(
                    "[{}{}] {:5.1} % {done}/{total} joint states, {:.0} msg/s",
                    "#".repeat(filled),
                    " ".repeat(30 - filled),
                    100.0 * fraction,
                    rate
                )
            }
            _ => format!("{done} joint states, {rate:.0} msg/s"),
        };
        eprint!("\r\x1b[2K{line}");
    }

    fn finish(&mut self, done: u64) {
        self.draw(done);
        eprintln!();
    }
}

#[allow(clippy::too_many_arguments)]
fn report(
    args: &ReplayArgs,
    model: &Model,
    model_source: &str,
    js_topic: &str,
    cmd_topic: &str,
    out_topics: &[String],
    outcome: &Outcome,
    jobs: usize,
    seconds: f64,
) {
    let rate = outcome.read[0] as f64 / seconds.max(1e-9);
    let skipped_js = outcome.problems.total("joint_states");
    let skipped_cmd = outcome.problems.total("effort_command");
    eprintln!(
        "spatial_dynamics replay: robot '{}' ({} coordinates) from {model_source}",
        model.name, model.nv
    );
    eprintln!(
        "read {} {js_topic} and {} {cmd_topic} messages in {seconds:.2} s ({rate:.0} joint states/s, {jobs} jobs)",
        outcome.read[0], outcome.read[1]
    );
    eprintln!(
        "wrote {}: {} {}, {} {}, {} {}",
        args.out.display(),
        outcome.written[0],
        out_topics[0],
        outcome.written[1],
        out_topics[1],
        outcome.written[2],
        out_topics[2]
    );
    for (what, topic, total) in [
        ("joint_states", js_topic, skipped_js),
        ("effort_command", cmd_topic, skipped_cmd),
    ] {
        if total > 0 {
            eprintln!("skipped {total} {topic} messages:");
        }
        print_problems(&outcome.problems, what);
    }
    let missing = outcome.problems.total("measured_dynamics");
    if missing > 0 {
        eprintln!("no {} for {missing} joint states:", out_topics[2]);
        print_problems(&outcome.problems, "measured_dynamics");
    }
    if outcome.log_time_backwards > 0 {
        eprintln!(
            "note: the log time went backwards {} times: messages were taken in storage order",
            outcome.log_time_backwards
        );
    }
    if args.json {
        let problems = |what: &str| -> Value {
            let mut kinds = serde_json::Map::new();
            for ((w, kind), p) in &outcome.problems.by_kind {
                if *w == what {
                    kinds.insert(
                        kind.to_string(),
                        json!({"count": p.count, "first": p.first, "first_log_time": p.first_log_time}),
                    );
                }
            }
            json!({"total": outcome.problems.total(what), "kinds": kinds})
        };
        let summary = json!({
            "model": {"name": model.name, "nv": model.nv, "source": model_source},
            "read": {js_topic: outcome.read[0], cmd_topic: outcome.read[1]},
            "written": {
                out_topics[0].as_str(): outcome.written[0],
                out_topics[1].as_str(): outcome.written[1],
                out_topics[2].as_str(): outcome.written[2],
            },
            "skipped": {js_topic: problems("joint_states"), cmd_topic: problems("effort_command")},
            "not_estimated": problems("measured_dynamics"),
            "log_time_backwards": outcome.log_time_backwards,
            "seconds": seconds,
            "joint_states_per_second": rate,
            "cpu_seconds": cpu_seconds(),
            "joint_states_per_cpu_second": cpu_seconds().map(|c| outcome.read[0] as f64 / c.max(1e-9)),
            "jobs": jobs,
        });
        println!("{summary}");
    }
}

/// CPU time of the whole process (every thread, user + system), from `/proc/self/stat`
/// (Linux, 100 ticks a second); `None` elsewhere.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces, inside parentheses): utime and
    // stime are the 12th and 13th.
    let rest = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: u64 = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    Some(ticks as f64 / 100.0)
}

fn print_problems(problems: &Problems, what: &str) {
    for ((w, kind), p) in &problems.by_kind {
        if *w == what {
            eprintln!(
                "  {:>9}  {kind} (first at log time {}.{:09}: {})",
                p.count,
                p.first_log_time / 1_000_000_000,
                p.first_log_time % 1_000_000_000,
                p.first
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The three-point formula is exact for a quadratic velocity on uneven steps; the one-sided
    /// ones for a linear one.
    #[test]
    fn differences_are_exact_for_polynomials_of_their_order() {
        let v = |t: f64| [3.0 * t * t - 2.0 * t + 1.0, -t * t];
        let dv = |t: f64| [6.0 * t - 2.0, -2.0 * t];
        let (t0, t1, t2) = (0.3, 0.31, 0.337);
        let mut out = [0.0; 2];
        assert!(velocity_derivative(
            Some((t1 - t0, &v(t0))),
            &v(t1),
            Some((t2 - t1, &v(t2))),
            &mut out
        ));
        for k in 0..2 {
            assert!((out[k] - dv(t1)[k]).abs() < 1e-9, "{out:?} vs {:?}", dv(t1));
        }
        let line = |t: f64| [2.0 * t + 1.0, -5.0 * t];
        assert!(velocity_derivative(
            None,
            &line(t0),
            Some((t1 - t0, &line(t1))),
            &mut out
        ));
        assert!((out[0] - 2.0).abs() < 1e-9 && (out[1] + 5.0).abs() < 1e-9);
        assert!(velocity_derivative(
            Some((t2 - t1, &line(t1))),
            &line(t2),
            None,
            &mut out
        ));
        assert!((out[0] - 2.0).abs() < 1e-9 && (out[1] + 5.0).abs() < 1e-9);
        assert!(!velocity_derivative(None, &line(t0), None, &mut out));
    }

    #[test]
    fn names_resolve_like_the_node() {
        assert_eq!(
            resolve("~/effort_command", "/spatial_dynamics"),
            "/spatial_dynamics/effort_command"
        );
        assert_eq!(resolve("joint_states", "/n"), "/joint_states");
        assert_eq!(resolve("/robot/joint_states", "/n"), "/robot/joint_states");
    }
}
