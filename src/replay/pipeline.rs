//! Three stages: the calling thread reads and decodes the bag in order into blocks of samples;
//! `jobs` workers compute and serialize whole blocks, each with its own scratch (no allocation
//! per message); one writer thread writes the blocks in order. Blocks are recycled.

use super::block::{Block, BLOCK};
use super::compute::{compute, Scratch};
use super::decode::Decoder;
use super::problems::Problems;
use super::progress::Progress;
use crate::bag::{Bag, Flow, McapWriter, Wanted};
use spatial_dynamics_core::{ForwardDynamicsMethod, Model};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Mutex;

/// What the pipeline counted.
pub struct Outcome {
    /// Messages read, by input: joint states, effort commands, commands.
    pub read: [u64; 3],
    /// Messages written, by output (in [`OUTPUTS`](super::OUTPUTS) order).
    pub written: [u64; 4],
    pub problems: Problems,
    pub log_time_backwards: u64,
}

/// Decodes here, computes in `jobs` workers, writes in one writer thread; blocks are recycled.
/// Stops with an error once `interrupted` is set (a signal), before the next message.
#[allow(clippy::too_many_arguments)]
pub fn pipeline(
    interrupted: &AtomicBool,
    bag: &Bag,
    wanted: &[Wanted<'_>],
    model: &Model,
    method: ForwardDynamicsMethod,
    jobs: usize,
    mut decoder: Decoder,
    mut writer: McapWriter,
    channels: [u16; 4],
    mut progress: Option<Progress>,
) -> Result<Outcome, String> {
    let (nq, nv) = (model.nq(), model.nv());
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
        for (k, builder) in builders.into_iter().enumerate() {
            let (work_rx, done_tx) = (&work_rx, done_tx.clone());
            let spawned = std::thread::Builder::new().spawn_scoped(scope, move || {
                let mut s = Scratch::new(model, builder);
                loop {
                    let next = work_rx.lock().map(|rx| rx.recv());
                    let Ok(Ok(mut block)) = next else { break };
                    block.error = compute(&mut block, model, method, channels, &mut s).err();
                    if done_tx.send(block).is_err() {
                        break;
                    }
                }
            });
            if let Err(e) = spawned {
                // The workers started end once the work channel closes.
                drop(work_tx);
                return Err(format!(
                    "cannot start worker thread {} of {jobs}: {e}",
                    k + 1
                ));
            }
        }
        drop(done_tx);
        let writer_thread = std::thread::Builder::new().spawn_scoped(scope, move || {
            let counts = write_blocks(&mut writer, done_rx, free_tx, channels)?;
            writer.finish()?;
            Ok::<_, String>(counts)
        });
        let writer_thread = match writer_thread {
            Ok(thread) => thread,
            Err(e) => {
                drop(work_tx);
                return Err(format!("cannot start the writer thread: {e}"));
            }
        };

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
        block.clear();
        block.lo = 0;
        block.base = 0;
        let mut send = |block: Box<Block>, hi: usize, tx: &Sender<Box<Block>>| {
            let mut block = block;
            block.hi = hi;
            block.seq = seq;
            seq += 1;
            tx.send(block).is_ok()
        };
        let mut failed = None;
        let result = bag.read(wanted, &mut |m| {
            if interrupted.load(Ordering::Relaxed) {
                return Err("interrupted by a signal: nothing written".into());
            }
            if m.log_time < decoder.last_log_time {
                decoder.log_time_backwards += 1;
            }
            decoder.last_log_time = m.log_time;
            decoder.read[m.topic] += 1;
            let topic = m.topic;
            match topic {
                1 => decoder.effort_command(m),
                2 => decoder.commands(m),
                _ => decoder.joint_state(m, &mut block),
            }
            if topic != 0 {
                return Ok(Flow::Continue);
            }
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
                next.clear();
                next.copy_sample(0, &block, n - 2, nq, nv);
                next.copy_sample(1, &block, n - 1, nq, nv);
                next.n = 2;
                next.lo = 1;
                next.base = decoder.committed - 1;
                let full = std::mem::replace(&mut block, next);
                if !send(full, n - 1, &work_tx) {
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
            send(block, n, &work_tx);
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
    channels: [u16; 4],
) -> Result<([u64; 4], Problems), String> {
    let mut pending: BTreeMap<u64, Box<Block>> = BTreeMap::new();
    let mut next = 0u64;
    let mut written = [0u64; 4];
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
