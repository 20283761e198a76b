//! Blocks of samples: joint states decoded in bag order, in model coordinates, and what the
//! workers made of them.

use super::problems::Problems;
use crate::bag::FinishedChunk;
use std::sync::Arc;

/// Samples per block of work: one MCAP chunk of about 1 MB (uncompressed) per block.
pub const BLOCK: usize = 1024;

/// A name order seen in the input: the message's names, the coordinates they fill, and the
/// output's `name[]` encoded once.
#[derive(Debug, Default)]
pub struct Order {
    pub names: Vec<String>,
    /// `(q index, v index)` of each named coordinate, in the message's order (passive joints left out).
    pub slots: Vec<(usize, usize)>,
    pub encoded_names: Vec<u8>,
}

/// Samples decoded in order, and what the workers made of them. Sample `lo − 1` (if `lo = 1`)
/// and sample `hi` (if `hi < n`) are neighbours from the blocks before and after, there for the
/// finite differences only.
pub struct Block {
    pub seq: u64,
    /// The name orders and frame ids of this block's samples (`order`, `frame` index them),
    /// each listed again only where it differs from the sample before: a block's lists never
    /// outgrow its samples, however many the bag holds.
    pub orders: Vec<Arc<Order>>,
    pub frames: Vec<String>,
    /// Number of sample `lo` among all valid joint states (the outputs' sequence numbers).
    pub base: u64,
    pub n: usize,
    pub lo: usize,
    pub hi: usize,
    pub log_time: Vec<u64>,
    pub stamp: Vec<(i32, u32)>,
    /// Time base of the differences, ns.
    pub t: Vec<i64>,
    pub frame: Vec<u32>,
    pub order: Vec<u32>,
    pub has_velocity: Vec<bool>,
    /// Sample `i` and `i − 1` are one segment: both have velocities, `0 < t_i − t_{i−1} ≤ max gap`.
    pub joins_prev: Vec<bool>,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub command: Vec<f64>,
    /// The message carried a (valid) effort: `effort` holds it, model order.
    pub has_effort: Vec<bool>,
    pub effort: Vec<f64>,
    /// The outputs, as one MCAP chunk with its message indexes.
    pub chunk: FinishedChunk,
    /// Why the chunk could not be made.
    pub error: Option<String>,
    pub problems: Problems,
}

impl Block {
    pub fn new(nq: usize, nv: usize) -> Block {
        let cap = BLOCK + 2;
        Block {
            seq: 0,
            orders: Vec::new(),
            frames: Vec::new(),
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
            has_effort: vec![false; cap],
            effort: vec![0.0; cap * nv],
            chunk: FinishedChunk::default(),
            error: None,
            problems: Problems::default(),
        }
    }

    /// Empties the block for reuse.
    pub fn clear(&mut self) {
        self.n = 0;
        self.orders.clear();
        self.frames.clear();
    }

    /// The index of `order` in this block's list, appended unless it is the last one.
    pub fn order_index(&mut self, order: &Arc<Order>) -> u32 {
        if !self.orders.last().is_some_and(|o| Arc::ptr_eq(o, order)) {
            self.orders.push(order.clone());
        }
        (self.orders.len() - 1) as u32
    }

    /// The index of `frame` in this block's list, appended unless it is the last one.
    pub fn frame_index(&mut self, frame: &str) -> u32 {
        if self.frames.last().map(String::as_str) != Some(frame) {
            self.frames.push(frame.to_string());
        }
        (self.frames.len() - 1) as u32
    }

    /// Copies sample `from` of `other` into slot `to`.
    pub fn copy_sample(&mut self, to: usize, other: &Block, from: usize, nq: usize, nv: usize) {
        self.log_time[to] = other.log_time[from];
        self.stamp[to] = other.stamp[from];
        self.t[to] = other.t[from];
        self.frame[to] = self.frame_index(&other.frames[other.frame[from] as usize]);
        self.order[to] = self.order_index(&other.orders[other.order[from] as usize]);
        self.has_velocity[to] = other.has_velocity[from];
        self.joins_prev[to] = other.joins_prev[from];
        self.q[to * nq..(to + 1) * nq].copy_from_slice(&other.q[from * nq..(from + 1) * nq]);
        self.v[to * nv..(to + 1) * nv].copy_from_slice(&other.v[from * nv..(from + 1) * nv]);
        self.command[to * nv..(to + 1) * nv]
            .copy_from_slice(&other.command[from * nv..(from + 1) * nv]);
        self.has_effort[to] = other.has_effort[from];
        self.effort[to * nv..(to + 1) * nv]
            .copy_from_slice(&other.effort[from * nv..(from + 1) * nv]);
    }
}
