//! Arguments as float64 rows: a C-contiguous float64 numpy array is borrowed as it is; anything
//! else (a list, another dtype, a strided view) is converted once by `numpy.ascontiguousarray`.
//! A 1-D argument is one state, a 2-D one N states (a row each); any other shape is a
//! `DynamicsError` naming the argument and the length the model needs.

use crate::errors::error;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// One argument, borrowed as float64 values, with the number of states it holds.
pub struct Rows<'py> {
    array: PyReadonlyArrayDyn<'py, f64>,
    /// `None` for one state (1-D), `Some(n)` for `n` rows (2-D).
    pub states: Option<usize>,
}

impl<'py> Rows<'py> {
    /// `value` as rows of `len` values, the argument called `name`.
    pub fn new(value: &Bound<'py, PyAny>, name: &str, len: usize) -> PyResult<Self> {
        let array = match value.extract::<PyReadonlyArrayDyn<'py, f64>>() {
            Ok(a) if a.is_c_contiguous() => a,
            _ => contiguous(value, name)?,
        };
        let shape = array.shape();
        let states = match *shape {
            [n] if n == len => None,
            [rows, n] if n == len => Some(rows),
            _ => {
                return Err(error(format!(
                    "{name} has shape {}, the model needs {len} values per state (a 1-D array of {len}, or 2-D with {len} columns)",
                    shape_text(shape)
                )))
            }
        };
        Ok(Rows { array, states })
    }

    /// Every value, row after row.
    pub fn values(&self) -> &[f64] {
        self.array
            .as_slice()
            .expect("the array was made C-contiguous")
    }
}

/// `numpy.ascontiguousarray(value, dtype=float64)`, or an error naming the argument.
#[cold]
fn contiguous<'py>(
    value: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let py = value.py();
    let numpy = py.import("numpy")?;
    let converted = numpy
        .getattr("ascontiguousarray")?
        .call1((value, numpy.getattr("float64")?))
        .map_err(|e| error(format!("{name} is not an array of numbers: {e}")))?;
    let array = converted
        .extract::<Bound<'py, PyArrayDyn<f64>>>()
        .map_err(|e| error(format!("{name} is not an array of numbers: {e}")))?;
    Ok(array.readonly())
}

/// A shape as Python prints it: `(3,)`, `(2, 3)`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The number of states of a call: `None` when every argument is 1-D, `Some(n)` when every one
/// is 2-D with `n` rows; mixing the two, or rows that differ, is an error naming the arguments.
pub fn states_of(args: &[(&str, &Rows<'_>)]) -> PyResult<Option<usize>> {
    let Some((first_name, first)) = args.first() else {
        return Ok(None);
    };
    for (name, rows) in &args[1..] {
        if rows.states != first.states {
            let describe = |s: Option<usize>| match s {
                None => "one state (1-D)".to_string(),
                Some(n) => format!("{n} states (2-D)"),
            };
            return Err(error(format!(
                "{name} holds {}, {first_name} {}: give every argument as 1-D, or every one as 2-D with the same rows",
                describe(rows.states),
                describe(first.states)
            )));
        }
    }
    Ok(first.states)
}
