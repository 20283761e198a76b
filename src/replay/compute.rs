//! Computing, in parallel: the dynamics of a block's samples ([`JointStateDynamics`], one
//! state at a time) encoded straight into one MCAP chunk of output messages.

use super::block::{Block, Order};
use crate::bag::{cdr, ChunkBuilder};
use crate::joint_states::differences::velocity_derivative;
use crate::joint_states::dynamics::JointStateDynamics;
use crate::joint_states::residual::effort_residual;
use spatial_dynamics_core::algorithms::JointStateInputs;
use spatial_dynamics_core::{ForwardDynamicsMethod, Model, Workspace};

/// A worker's scratch: its workspace, `v`-sized buffers and chunk builder.
pub struct Scratch {
    ws: Workspace,
    builder: ChunkBuilder,
    /// The measured acceleration.
    a: Vec<f64>,
    /// The effort residual.
    r: Vec<f64>,
    dynamics: JointStateDynamics,
}

impl Scratch {
    pub fn new(model: &Model, builder: ChunkBuilder) -> Scratch {
        Scratch {
            ws: Workspace::new(model),
            builder,
            a: vec![0.0; model.nv()],
            r: vec![0.0; model.nv()],
            dynamics: JointStateDynamics::new(model),
        }
    }
}

/// The dynamics of samples `lo..hi` of a block, serialized into one MCAP chunk; `channels`
/// are the channel ids of the outputs.
pub fn compute(
    block: &mut Block,
    model: &Model,
    method: ForwardDynamicsMethod,
    channels: [u16; 4],
    s: &mut Scratch,
) -> Result<(), String> {
    let (nq, nv) = (model.nq(), model.nv());
    for i in block.lo..block.hi {
        let q = &block.q[i * nq..(i + 1) * nq];
        let v = &block.v[i * nv..(i + 1) * nv];
        let command = &block.command[i * nv..(i + 1) * nv];
        let order = &block.orders[block.order[i] as usize];
        let (sec, nanosec) = block.stamp[i];
        let frame = block.frames[block.frame[i] as usize].as_str();
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
        let evaluated = s.dynamics.evaluate(model, &mut s.ws, method, &input);
        let d = &s.dynamics;
        let (g, qdd, tau) = (d.gravity(), d.acceleration(), d.inverse_dynamics());

        // The node's two outputs: both or neither, as the node publishes them.
        match evaluated.node {
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

        // Inverse dynamics of the measured motion, and what the measured effort has beyond it.
        let has_effort = block.has_effort[i];
        let (kind, e) = match (measured, evaluated.measured) {
            (Err((kind, e)), _) => (kind, e.to_string()),
            (Ok(()), Err(e)) => ("inverse dynamics failed", e),
            (Ok(()), Ok(())) => {
                let mut w = start!(2);
                w.f64s(rate(v));
                w.f64s(rate(&s.a));
                w.f64s(rate(tau));
                s.builder.end_message();
                if !has_effort {
                    continue;
                }
                let effort = &block.effort[i * nv..(i + 1) * nv];
                match effort_residual(effort, tau, &mut s.r) {
                    Ok(()) => {
                        let mut w = start!(3);
                        w.f64s(rate(v));
                        w.f64s(rate(&s.r));
                        s.builder.end_message();
                    }
                    Err((kind, e)) => block.problems.add("effort_residual", kind, log_time, e),
                }
                continue;
            }
        };
        if has_effort {
            block
                .problems
                .add("effort_residual", kind, log_time, e.clone());
        }
        block.problems.add("measured_dynamics", kind, log_time, e);
    }
    s.builder.finish(&mut block.chunk)
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
