//! Decoding, in bag order: joint states into blocks of samples (model coordinates, name orders
//! and frames numbered), commands (`~/effort_command` by name, `~/commands` in
//! `command_joints` order) into the command state.

use super::block::{Block, Order};
use super::problems::Problems;
use super::TimeSource;
use crate::bag::{cdr, RawMessage};
use crate::joint_states::commands::Commands;
use crate::joint_states::differences::joins;
use crate::joint_states::joint_map::JointMap;
use crate::joint_states::residual::read_effort;
use spatial_dynamics_core::Model;
use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;

/// Reads joint states and commands into blocks, in bag order.
pub struct Decoder {
    nq: usize,
    nv: usize,
    map: JointMap,
    commands: Commands,
    time_source: TimeSource,
    max_gap_ns: i64,
    ranges: Vec<Range<usize>>,
    names: Vec<String>,
    values: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
    /// The order `map` last matched (valid while `Some`).
    current_order: Option<Arc<Order>>,
    /// Every name order seen, by its names: each matched against the model once.
    orders: HashMap<Vec<String>, Arc<Order>>,
    /// `(t, has velocity)` of the last sample decoded.
    prev: Option<(i64, bool)>,
    pub problems: Problems,
    /// Messages read, by input (index in the `wanted` list).
    pub read: [u64; 3],
    /// Joint states decoded so far (valid ones).
    pub committed: u64,
    pub last_log_time: u64,
    pub log_time_backwards: u64,
}

impl Decoder {
    /// A decoder for `map`'s model; `commands` holds the command state (zero effort).
    pub fn new(
        model: &Model,
        map: JointMap,
        commands: Commands,
        time_source: TimeSource,
        max_gap_ns: i64,
    ) -> Decoder {
        Decoder {
            nq: model.nq(),
            nv: model.nv(),
            map,
            commands,
            time_source,
            max_gap_ns,
            ranges: Vec::new(),
            names: Vec::new(),
            values: Vec::new(),
            current_order: None,
            orders: HashMap::new(),
            velocity: Vec::new(),
            effort: Vec::new(),
            prev: None,
            problems: Problems::default(),
            read: [0; 3],
            committed: 0,
            last_log_time: 0,
            log_time_backwards: 0,
        }
    }

    /// A joint state into slot `block.n`; on success the block has one more sample.
    pub fn joint_state(&mut self, msg: RawMessage<'_>, block: &mut Block) {
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
        view.velocity.read_into(&mut self.velocity);
        let q = &mut block.q[i * nq..(i + 1) * nq];
        let v = &mut block.v[i * nv..(i + 1) * nv];
        let has_velocity = match self.map.scatter_state(&self.values, &self.velocity, q, v) {
            Ok(has) => has,
            Err((kind, e)) => return self.skip(kind, msg.log_time, e),
        };
        // A bad effort costs the residual only; the other outputs stand.
        view.effort.read_into(&mut self.effort);
        let effort = &mut block.effort[i * nv..(i + 1) * nv];
        block.has_effort[i] = match read_effort(&self.map, &self.effort, effort) {
            Ok(has) => has,
            Err((kind, e)) => {
                self.problems.add("effort_residual", kind, msg.log_time, e);
                false
            }
        };
        let t = match self.time_source {
            TimeSource::Header => i64::from(view.sec) * 1_000_000_000 + i64::from(view.nanosec),
            TimeSource::Log => msg.log_time as i64,
        };
        let joins_prev = joins(self.prev, t, has_velocity, self.max_gap_ns);
        self.prev = Some((t, has_velocity));
        block.frame[i] = block.frame_index(view.frame_id);
        block.order[i] = block.order_index(&order);
        block.log_time[i] = msg.log_time;
        block.stamp[i] = (view.sec, view.nanosec);
        block.t[i] = t;
        block.has_velocity[i] = has_velocity;
        block.joins_prev[i] = joins_prev;
        block.command[i * nv..(i + 1) * nv].copy_from_slice(self.commands.effort());
        block.n += 1;
        self.committed += 1;
    }

    fn skip(&mut self, kind: &'static str, log_time: u64, message: String) {
        self.problems.add("joint_states", kind, log_time, message);
    }

    /// The name order of a message, matching the names only when they differ from the last.
    fn order_of(
        &mut self,
        view: &cdr::JointStateView<'_>,
    ) -> Result<Arc<Order>, (&'static str, String)> {
        if let Some(current) = &self.current_order {
            let known = &current.names;
            if known.len() == self.ranges.len()
                && known
                    .iter()
                    .zip(&self.ranges)
                    .all(|(k, r)| k.as_bytes() == view.name_bytes(r))
            {
                return Ok(current.clone());
            }
        }
        self.current_order = None;
        read_names(view, &self.ranges, &mut self.names).map_err(|e| ("bad joint names", e))?;
        self.map
            .match_names(&self.names, "name")
            .map_err(|e| ("bad joint names", e))?;
        let order = match self.orders.get(&self.names) {
            Some(order) => order.clone(),
            None => {
                let order = Arc::new(Order {
                    names: self.names.clone(),
                    slots: self.map.answer_order().map(|s| self.map.slot(s)).collect(),
                    encoded_names: cdr::encode_strings(&self.map.answer_names()),
                });
                self.orders.insert(self.names.clone(), order.clone());
                order
            }
        };
        self.current_order = Some(order.clone());
        Ok(order)
    }

    /// An effort command (sensor_msgs/JointState, by name): it holds until the next command.
    pub fn effort_command(&mut self, msg: RawMessage<'_>) {
        let result = (|| {
            let view = cdr::parse_joint_state(msg.data, &mut self.ranges)
                .map_err(|e| ("unreadable message", e))?;
            read_names(&view, &self.ranges, &mut self.names).map_err(|e| ("bad joint names", e))?;
            view.effort.read_into(&mut self.values);
            self.commands.set_effort_command(&self.names, &self.values)
        })();
        if let Err((kind, e)) = result {
            self.problems.add("effort_command", kind, msg.log_time, e);
        }
    }

    /// A command (std_msgs/Float64MultiArray, in `command_joints` order): it holds until the
    /// next command of either kind.
    pub fn commands(&mut self, msg: RawMessage<'_>) {
        let result = (|| {
            let data =
                cdr::parse_float64_multi_array(msg.data).map_err(|e| ("unreadable message", e))?;
            data.read_into(&mut self.values);
            self.commands.set_commands(&self.values)
        })();
        if let Err((kind, e)) = result {
            self.problems.add("commands", kind, msg.log_time, e);
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
