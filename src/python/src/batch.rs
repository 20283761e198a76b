//! One kernel (a library function writing its results into output slices) run over one state
//! or over N states, with workspaces kept by the model between calls ([`Workspaces`]). N states
//! are computed with the GIL released, from inputs that are the call's own: another Python
//! thread may write the arguments meanwhile, so a float64 array that one state reads in place
//! is copied, with the GIL held, for N (an argument converted to float64 is a new array
//! already). The calling thread takes blocks of rows from a shared queue, reading each block's
//! inputs and writing its results in place in the outputs'; after its first block, the time
//! that block took tells how many more threads the remaining rows are worth (none for a small
//! batch, at most `std::thread::available_parallelism()` in all, asked once per process), which
//! join it on the queue, each with a workspace of the pool. A block goes to a block kernel (a
//! library function over many rows, e.g. `rnea_rows`) or, by [`run`], to the one-state kernel
//! row by row. The outputs are numpy arrays allocated once per call by `numpy.empty` (a size
//! numpy cannot allocate is its `MemoryError` or `ValueError`), every value written by the
//! kernels: one state's results have the per-state shape, N states' results `(N, *shape)`, row
//! `i` being state `i`'s. `numpy.empty`, unlike `numpy.zeros`, keeps the GIL: no other thread
//! runs between the call and the copy of its float64 inputs (unless numpy releases the GIL to
//! convert another argument), which are then the arguments as they were at the call.

use crate::arrays::{shape_text, states_of, Arg};
use crate::errors::{error, from_library};
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::PyTuple;
use spatial_dynamics_core::{DynamicsError, Model, Workspace};
use std::slice::ChunksMut;
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::thread;
use std::time::{Duration, Instant};

/// The workspaces of one model not in use, kept between calls so that a call does not build
/// one: a call takes one per thread it runs on (building one when none is left) and gives it
/// back after, up to one kept per core.
pub struct Workspaces {
    spare: Mutex<Vec<Workspace>>,
}

impl Workspaces {
    /// A pool holding one workspace of `model`.
    pub fn new(model: &Model) -> Self {
        Workspaces {
            spare: Mutex::new(vec![Workspace::new(model)]),
        }
    }

    /// A workspace of `model`: a kept one, or a new one when none is left.
    fn take(&self, model: &Model) -> Workspace {
        let kept = self.spare.lock().unwrap_or_else(|e| e.into_inner()).pop();
        kept.unwrap_or_else(|| Workspace::new(model))
    }

    /// `workspace` back into the pool, unless it holds one per core already.
    fn give(&self, workspace: Workspace) {
        let mut spare = self.spare.lock().unwrap_or_else(|e| e.into_inner());
        if spare.len() < cores() {
            spare.push(workspace);
        }
    }
}

/// The time of work an extra thread must have before one is started for it: well above what
/// starting and joining a thread costs (tens of microseconds).
const THREAD_WORK: Duration = Duration::from_micros(100);

/// Runs `kernel` on the `inputs` (argument name, value, values per state) into outputs of the
/// per-state shapes `outputs`. The kernel reads one state's inputs and fills every value of
/// one state's outputs (row-major); N states go to it one row at a time.
pub fn run<'py, const I: usize, const O: usize, K>(
    py: Python<'py>,
    model: &Model,
    workspaces: &Workspaces,
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
    run_blocks(py, model, workspaces, inputs, outputs, &kernel, rows)
}

/// [`run`] with a kernel of its own for N states: `block` gets a block's rows (their count,
/// then each input's and output's values, row after row) and returns an error with the row of
/// the block it is at. The arguments' dtypes and shapes are checked before the outputs are
/// allocated, and the outputs allocated before any argument is copied.
pub fn run_blocks<'py, const I: usize, const O: usize, K, B>(
    py: Python<'py>,
    model: &Model,
    workspaces: &Workspaces,
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
    let mut args = Vec::with_capacity(I);
    for (name, value, len) in inputs {
        args.push(Arg::inspect(value, name, len)?);
    }
    let states = states_of(&args)?;
    let mut arrays = Vec::with_capacity(O);
    for per_state in outputs {
        let mut shape = Vec::with_capacity(per_state.len() + 1);
        shape.extend(states);
        shape.extend_from_slice(per_state);
        arrays.push(empty(py, &shape)?);
    }
    let arrays: [Bound<'py, PyArrayDyn<f64>>; O] = arrays
        .try_into()
        .map_err(|_| error("one result array per output was not made"))?;
    // N states are read with the GIL released: their values must be the call's own.
    let mut rows = Vec::with_capacity(I);
    for arg in &args {
        rows.push(arg.rows(states.is_some())?);
    }
    let mut ins: [&[f64]; I] = [&[]; I];
    for (k, r) in rows.iter().enumerate() {
        ins[k] = r.values()?;
    }
    let mut writers = Vec::with_capacity(O);
    for array in &arrays {
        writers.push(
            array
                .try_readwrite()
                .map_err(|e| error(format!("a result array cannot be written: {e}")))?,
        );
    }
    let mut slices = Vec::with_capacity(O);
    for writer in &mut writers {
        slices.push(
            writer
                .as_slice_mut()
                .map_err(|_| error("a result array is not contiguous"))?,
        );
    }
    let slices: [&mut [f64]; O] = slices
        .try_into()
        .map_err(|_| error("one result slice per output was not made"))?;
    match states {
        None => {
            let mut ws = workspaces.take(model);
            let result = kernel(&mut ws, ins, slices);
            workspaces.give(ws);
            result.map_err(from_library)?;
        }
        Some(n) => {
            let lens = inputs.map(|i| i.2);
            let sizes = outputs.map(|shape| shape.iter().product::<usize>());
            py.detach(|| in_parallel(model, workspaces, n, ins, lens, slices, sizes, &block))
                .map_err(|(row, e)| error(format!("row {row}: {e}")))?;
        }
    }
    drop(writers);
    Ok(arrays)
}

/// `numpy.empty(shape)` (float64, C order, values unset: the kernels write every one). A shape
/// whose bytes overflow the address space is a `MemoryError` naming it; numpy's own errors
/// (`MemoryError` when the memory is not there) propagate unchanged. Unlike `numpy.zeros`, it
/// keeps the GIL.
pub(crate) fn empty<'py>(
    py: Python<'py>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    static EMPTY: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    let bytes = shape
        .iter()
        .try_fold(size_of::<f64>(), |bytes, &n| bytes.checked_mul(n));
    if bytes.is_none_or(|b| isize::try_from(b).is_err()) {
        return Err(PyMemoryError::new_err(format!(
            "a result of shape {} would take more bytes than memory can address",
            shape_text(shape)
        )));
    }
    EMPTY
        .import(py, "numpy", "empty")?
        .call1((PyTuple::new(py, shape)?,))?
        .cast_into::<PyArrayDyn<f64>>()
        .map_err(|_| error("numpy.empty did not return a float64 array"))
}

/// The `n` states: the calling thread takes blocks of rows in order from a shared queue; the
/// time of its first block estimates the remaining work, and one more thread is started per
/// [`THREAD_WORK`] of it (at most `std::thread::available_parallelism()` threads in all), each
/// with a workspace of `workspaces`. Taking blocks from a queue means a thread slowed by another
/// process on its core takes fewer of them. On an error no further block is taken; each thread
/// stops at its first, and the one of the lowest row is returned: every block before it was
/// taken earlier and is finished, so it is the batch's first error by row.
#[allow(clippy::too_many_arguments)]
fn in_parallel<const I: usize, const O: usize, B>(
    model: &Model,
    workspaces: &Workspaces,
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
    let cores = cores();
    let rows_per_block = block_rows(n, cores);
    // Each output cut into blocks of `rows_per_block` rows (a state with no values has none:
    // its blocks are empty slices).
    let cuts = chunked(outs, sizes.map(|size| rows_per_block * size));
    let queue = Mutex::new(Blocks {
        cuts,
        next_row: 0,
        failed: false,
    });
    // One block from the queue, `Ok(false)` when none is left.
    let one = |ws: &mut Workspace| -> Result<bool, (usize, DynamicsError)> {
        let Some((first, outputs)) = take(&queue, n, rows_per_block) else {
            return Ok(false);
        };
        let end = (first + rows_per_block).min(n);
        let inputs: [&[f64]; I] = std::array::from_fn(|k| &ins[k][first * lens[k]..end * lens[k]]);
        if let Err((row, e)) = block(ws, end - first, inputs, outputs) {
            lock(&queue).failed = true;
            return Err((first + row, e));
        }
        Ok(true)
    };
    let work = |ws: &mut Workspace| -> Result<(), (usize, DynamicsError)> {
        while one(ws)? {}
        Ok(())
    };
    let results = thread::scope(|scope| {
        let mut ws = workspaces.take(model);
        let started = Instant::now();
        let first = one(&mut ws);
        let helpers = match first {
            Ok(_) => {
                let done = rows_per_block.min(n);
                helpers(started.elapsed(), done, n - done, cores)
            }
            Err(_) => 0,
        };
        let handles: Vec<_> = (0..helpers)
            .map(|_| {
                scope.spawn(|| {
                    let mut ws = workspaces.take(model);
                    let result = work(&mut ws);
                    workspaces.give(ws);
                    result
                })
            })
            .collect();
        let mine = first.and_then(|_| work(&mut ws));
        workspaces.give(ws);
        let mut results = vec![mine];
        for handle in handles {
            results.push(
                handle
                    .join()
                    .unwrap_or_else(|p| std::panic::resume_unwind(p)),
            );
        }
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

/// Threads to start besides the calling one for `remaining` rows, when `done` rows took
/// `elapsed`: one per [`THREAD_WORK`] of the remaining rows' estimated time, at most
/// `cores - 1`.
fn helpers(elapsed: Duration, done: usize, remaining: usize, cores: usize) -> usize {
    let per_row = elapsed.as_secs_f64() / done.max(1) as f64;
    let estimate = per_row * remaining as f64;
    let threads = (estimate / THREAD_WORK.as_secs_f64()).floor();
    // `as` saturates: a NaN or huge estimate stays in range before the `min`.
    (threads as usize).min(cores.saturating_sub(1))
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
