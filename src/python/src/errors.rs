//! `DynamicsError`: every failure of the module, a subclass of `ValueError` whose message is
//! the library's (naming the joint, coordinate, frame or file at fault) or names the argument
//! whose shape or type is wrong.

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
