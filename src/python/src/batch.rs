//! One kernel (a library function writing its results into output slices) run over one state,
//! with the model's own workspace, or over N states split across
//! `std::thread::available_parallelism()` scoped threads, each with a workspace of its own, the
//! GIL released. The outputs are numpy arrays allocated once per call: one state's results
//! have the per-state shape, N states' results `(N, *shape)`, row `i` being state `i`'s.

use crate::arrays::{states_of, Rows};
use crate::errors::{error, from_library};
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::prelude::*;
use spatial_dynamics_core::{DynamicsError, Model, Workspace};
use std::sync::Mutex;
use std::thread;

/// Runs `kernel` on the `inputs` (argument name, value, values per state) into outputs of the
/// per-state shapes `outputs`. The kernel reads one state's inputs and fills every value of
/// one state's outputs (row-major).
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
            py.detach(|| in_parallel(model, n, ins, lens, slices, sizes, &kernel))
                .map_err(|(row, e)| error(format!("row {row}: {e}")))?;
        }
    }
    drop(writers);
    Ok(arrays)
}

/// The `n` states over scoped threads: the first error by row, if any, with its row.
fn in_parallel<const I: usize, const O: usize, K>(
    model: &Model,
    n: usize,
    ins: [&[f64]; I],
    lens: [usize; I],
    outs: [&mut [f64]; O],
    sizes: [usize; O],
    kernel: &K,
) -> Result<(), (usize, DynamicsError)>
where
    K: Fn(&mut Workspace, [&[f64]; I], [&mut [f64]; O]) -> Result<(), DynamicsError> + Sync,
{
    if n == 0 {
        return Ok(());
    }
    let threads = thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(n);
    let per_thread = n.div_ceil(threads);
    let count = |t: usize| per_thread.min(n.saturating_sub(t * per_thread));
    // Each output cut into the threads' blocks of rows.
    let mut blocks: Vec<_> = outs
        .into_iter()
        .zip(sizes)
        .map(|(out, size)| {
            let mut cut = Vec::with_capacity(threads);
            let mut rest = out;
            for t in 0..threads {
                let (block, tail) = rest.split_at_mut(count(t) * size);
                cut.push(block);
                rest = tail;
            }
            cut.into_iter()
        })
        .collect();
    thread::scope(|scope| {
        let mut handles = Vec::with_capacity(threads);
        for t in 0..threads {
            let (first, count) = (t * per_thread, count(t));
            // Each output's block as rows of one state's values (a state with no values has
            // no rows: it gets empty slices).
            let mut rows: [std::slice::ChunksMut<f64>; O] = std::array::from_fn(|k| {
                let block = blocks[k].next().expect("one block a thread");
                block.chunks_mut(sizes[k].max(1))
            });
            handles.push(scope.spawn(move || {
                let mut ws = Workspace::new(model);
                for row in first..first + count {
                    let inputs: [&[f64]; I] =
                        std::array::from_fn(|k| &ins[k][row * lens[k]..(row + 1) * lens[k]]);
                    let outputs = rows.each_mut().map(|r| r.next().unwrap_or_default());
                    kernel(&mut ws, inputs, outputs).map_err(|e| (row, e))?;
                }
                Ok(())
            }));
        }
        handles
            .into_iter()
            .map(|h| h.join().expect("a batch thread panicked"))
            .collect::<Result<Vec<()>, _>>()
            .map(|_| ())
    })
}
