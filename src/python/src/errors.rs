//! `DynamicsError`, a subclass of `ValueError`: what the library refuses, its message the
//! library's (naming the joint, coordinate, frame or file at fault), and an argument of the
//! wrong shape, naming it. Other failures raise Python's own exceptions: `TypeError` for an
//! argument that is not real numbers, the `OSError` subclass of its cause for a URDF file that
//! cannot be read, `MemoryError` for results too big to allocate.

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::PyErr;

create_exception!(
    spatial_dynamics,
    DynamicsError,
    PyValueError,
    "A computation or model the library refuses: bad input (NaN, unknown frame, wrong shape), a URDF it cannot build. A ValueError."
);

/// `DynamicsError(message)`.
pub fn error(message: impl Into<String>) -> PyErr {
    DynamicsError::new_err(message.into())
}

/// `DynamicsError` with the `Display` of a library error.
pub fn from_library(e: impl std::fmt::Display) -> PyErr {
    DynamicsError::new_err(e.to_string())
}
