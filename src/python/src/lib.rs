//! `spatial_dynamics`: the library [`spatial_dynamics_core`] from Python, numpy `float64` in and
//! out. One state is 1-D arrays; N states are 2-D arrays (one state a row), computed with the
//! GIL released (on every core when the batch is worth it) and returned stacked.
//!
//! | module | holds |
//! |---|---|
//! | [`model`] | the `Model` class and its methods |
//! | [`arrays`] | arguments checked (real numbers, shapes named in errors), read as float64 rows |
//! | [`batch`] | one kernel run over one state or N rows, small batches on the calling thread, with the model's kept workspaces |
//! | [`errors`] | `DynamicsError`, a `ValueError` with the library's message |

// PyO3's macros expand to code that needs `unsafe`; this crate writes none of its own.
#![deny(unsafe_code)]

pub mod arrays;
pub mod batch;
pub mod errors;
pub mod model;

use pyo3::prelude::*;

/// The Python module `spatial_dynamics`.
#[pymodule]
fn spatial_dynamics(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<model::Model>()?;
    m.add("DynamicsError", m.py().get_type::<errors::DynamicsError>())?;
    Ok(())
}
