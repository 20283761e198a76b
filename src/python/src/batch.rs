//! One kernel (a library function writing its results into output slices) run over one state,
//! with the model's own workspace, or over N states on `std::thread::available_parallelism()`
//! (asked once per process) scoped threads, the GIL released: each thread has a workspace of
//! its own and takes blocks of rows from a shared queue, reading the block's inputs in place in
//! the arguments' buffers and writing its results in place in the outputs'. A block goes to a
//! block kernel (a library function over many rows, e.g. `rnea_rows`) or, by [`run`], to the
//! one-state kernel row by row. The outputs are numpy arrays allocated once per call: one
//! state's results have the per-state shape, N states' results `(N, *shape)`, row `i` being
//! state `i`'s.

use crate::arrays::{states_of, Rows};
use crate::errors::{error, from_library};
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::prelude::*;
use spatial_dynamics_core::{DynamicsError, Model, Workspace};
use std::slice::ChunksMut;
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::thread;

/// Runs `kernel` on the `inputs` (argument name, value, values per state) into outputs of the
/// per-state shapes `outputs`. The kernel reads one state's inputs and fills every value of
/// one state's outputs (row-major); N states go to it one row at a time.
pub fn run<'py, const I: usize, const O: usize, K>(
    py: Python<'py>,
    model: &Model,
    workspace: &Mutex<Workspace>,
    inputs: [(&str, &Bound<'py, PyAny>, usize); I],
    outputs: [&[usize]; O],
    kernel: K,
) -> PyResult<[Bound<'py, PyArrayDyn<f64>>; O]>
where
    K: Fn(&mut Workspace, [&[f64]; I], [&mut [f64]; O]) -> Result<(), DynamicsError> + Sync,
{
    let lens = inputs.map(|i| i.2);
    let sizes = outputs.map(|shape| shape.iter().product::<usize>());
    let rows = |ws: &mut Workspace, rows: usize, ins: [&[f64]; I], outs: [&mut [f64]; O]| {
        one_by_one(ws, rows, ins, outs, lens, sizes, &kernel)
    };
    run_blocks(py, model, workspace, inputs, outputs, &kernel, rows)
}

/// [`run`] with a kernel of its own for N states: `block` gets a block's rows (their count,
/// then each input's and output's values, row after row) and returns an error with the row of
/// the block it is at.
pub fn run_blocks<'py, const I: usize, const O: usize, K, B>(
    py: Python<'py>,
    model: &Model,
    workspace: &Mutex<Workspace>,
    inputs: [(&str, &Bound<'py, PyAny>, usize); I],
    outputs: [&[usize]; O],
    kernel: &K,
    block: B,
) -> PyResult<[Bound<'py, PyArrayDyn<f64>>; O]>
where
    K: Fn(&mut Workspace, [&[f64]; I], [&mut [f64]; O]) -> Result<(), DynamicsError>,
    B: Fn(
            &mut Workspace,
            usize,
            [&[f64]; I],
            [&mut [f64]; O],
        ) -> Result<(), (usize, DynamicsError)>
        + Sync,
{
    let mut rows = Vec::with_capacity(I);
    for (name, value, len) in inputs {
        rows.push(Rows::new(value, name, len)?);
    }
    let named: Vec<(&str, &Rows)> = inputs.iter().map(|i| i.0).zip(rows.iter()).collect();
    let states = states_of(&named)?;
    let arrays: [Bound<'py, PyArrayDyn<f64>>; O] = std::array::from_fn(|k| {
        let mut shape = Vec::with_capacity(outputs[k].len() + 1);
        shape.extend(states);
        shape.extend_from_slice(outputs[k]);
        PyArrayDyn::zeros(py, shape, false)
    });
    let mut writers = arrays.each_ref().map(|a| a.readwrite());
    let mut slices = writers
        .each_mut()
        .map(|w| w.as_slice_mut().expect("a new array is contiguous"));
    let ins: [&[f64]; I] = std::array::from_fn(|k| rows[k].values());
    match states {
        None => {
            let mut ws = workspace.lock().unwrap_or_else(|e| e.into_inner());
            kernel(&mut ws, ins, slices.each_mut().map(|s| &mut **s)).map_err(from_library)?;
        }
        Some(n) => {
            let lens = inputs.map(|i| i.2);
            let sizes = outputs.map(|shape| shape.iter().product::<usize>());
            py.detach(|| in_parallel(model, n, ins, lens, slices, sizes, &block))
                .map_err(|(row, e)| error(format!("row {row}: {e}")))?;
        }
    }
    drop(writers);
    Ok(arrays)
}

/// The `n` states over `std::thread::available_parallelism()` threads (the calling one among
/// them), which take blocks of rows in order from a shared queue, so a thread slowed by another
/// process on its core takes fewer of them. On an error no further block is taken; each thread
/// stops at its first, and the one of the lowest row is returned: every block before it was
/// taken earlier and is finished, so it is the batch's first error by row.
fn in_parallel<const I: usize, const O: usize, B>(
    model: &Model,
    n: usize,
    ins: [&[f64]; I],
    lens: [usize; I],
    outs: [&mut [f64]; O],
    sizes: [usize; O],
    block: &B,
) -> Result<(), (usize, DynamicsError)>
where
    B: Fn(
            &mut Workspace,
            usize,
            [&[f64]; I],
            [&mut [f64]; O],
        ) -> Result<(), (usize, DynamicsError)>
        + Sync,
{
    if n == 0 {
        return Ok(());
    }
    let threads = cores().min(n);
    let rows_per_block = block_rows(n, threads);
    // Each output cut into blocks of `rows_per_block` rows (a state with no values has none:
    // its blocks are empty slices).
    let cuts = chunked(outs, sizes.map(|size| rows_per_block * size));
    let queue = Mutex::new(Blocks {
        cuts,
        next_row: 0,
        failed: false,
    });
    let work = || -> Result<(), (usize, DynamicsError)> {
        let mut ws = Workspace::new(model);
        while let Some((first, outputs)) = take(&queue, n, rows_per_block) {
            let end = (first + rows_per_block).min(n);
            let inputs: [&[f64]; I] =
                std::array::from_fn(|k| &ins[k][first * lens[k]..end * lens[k]]);
            if let Err((row, e)) = block(&mut ws, end - first, inputs, outputs) {
                lock(&queue).failed = true;
                return Err((first + row, e));
            }
        }
        Ok(())
    };
    let results = thread::scope(|scope| {
        let handles: Vec<_> = (1..threads).map(|_| scope.spawn(work)).collect();
        let mut results = vec![work()];
        results.extend(
            handles
                .into_iter()
                .map(|h| h.join().expect("a batch thread panicked")),
        );
        results
    });
    match results
        .into_iter()
        .filter_map(Result::err)
        .min_by_key(|e| e.0)
    {
        Some(first) => Err(first),
        None => Ok(()),
    }
}

/// `rows` states through the one-state `kernel`, one at a time (`lens` input and `sizes` output
/// values a state), stopping at the first error, with its row.
fn one_by_one<const I: usize, const O: usize, K>(
    ws: &mut Workspace,
    rows: usize,
    ins: [&[f64]; I],
    outs: [&mut [f64]; O],
    lens: [usize; I],
    sizes: [usize; O],
    kernel: &K,
) -> Result<(), (usize, DynamicsError)>
where
    K: Fn(&mut Workspace, [&[f64]; I], [&mut [f64]; O]) -> Result<(), DynamicsError>,
{
    let mut cut = chunked(outs, sizes);
    for row in 0..rows {
        let inputs: [&[f64]; I] =
            std::array::from_fn(|k| &ins[k][row * lens[k]..(row + 1) * lens[k]]);
        let outputs = cut.each_mut().map(|r| r.next().unwrap_or_default());
        kernel(ws, inputs, outputs).map_err(|e| (row, e))?;
    }
    Ok(())
}

/// `std::thread::available_parallelism()`, asked once per process: on Linux it reads the
/// cgroup's CPU quota from files, tens of microseconds a call.
fn cores() -> usize {
    static CORES: OnceLock<usize> = OnceLock::new();
    *CORES.get_or_init(|| thread::available_parallelism().map_or(1, |t| t.get()))
}

/// Each slice cut into chunks of its `sizes` values (a size of zero: no chunk).
fn chunked<'a, const O: usize>(
    slices: [&'a mut [f64]; O],
    sizes: [usize; O],
) -> [ChunksMut<'a, f64>; O] {
    let mut cut = slices
        .into_iter()
        .zip(sizes)
        .map(|(slice, size)| slice.chunks_mut(size.max(1)));
    std::array::from_fn(|_| cut.next().expect("one chunking per slice"))
}

/// Rows a block holds: about 16 blocks a thread (for balance), at most 1024 rows (a few hundred
/// microseconds of the cheapest kernels, so the queue's lock is taken rarely).
fn block_rows(n: usize, threads: usize) -> usize {
    n.div_ceil(16 * threads).clamp(1, 1024)
}

/// The blocks of rows not yet taken: each output's remaining blocks, the first row of the next,
/// and whether a thread has failed (then none is handed out).
struct Blocks<'a, const O: usize> {
    cuts: [ChunksMut<'a, f64>; O],
    next_row: usize,
    failed: bool,
}

/// The next block: its first row and each output's slice of it; `None` when every block is
/// taken or a thread has failed.
fn take<'a, const O: usize>(
    queue: &Mutex<Blocks<'a, O>>,
    n: usize,
    rows_per_block: usize,
) -> Option<(usize, [&'a mut [f64]; O])> {
    let mut blocks = lock(queue);
    if blocks.failed || blocks.next_row >= n {
        return None;
    }
    let first = blocks.next_row;
    blocks.next_row += rows_per_block;
    Some((
        first,
        blocks.cuts.each_mut().map(|c| c.next().unwrap_or_default()),
    ))
}

/// The queue, whether or not another thread panicked holding it (its state stays consistent:
/// each change is one assignment).
fn lock<'q, 'a, const O: usize>(queue: &'q Mutex<Blocks<'a, O>>) -> MutexGuard<'q, Blocks<'a, O>> {
    queue.lock().unwrap_or_else(|e| e.into_inner())
}
