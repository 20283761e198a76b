//! Return codes, the calling thread's last error message, and [`guard`]: the frame every entry
//! point runs in, which turns a failure or a panic into a code and a message.

use spatial_dynamics_core::{DynamicsError, Model, ModelError};
use std::cell::RefCell;
use std::ffi::{c_char, c_int, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;

/// What a call returns (as an `int`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum sd_status {
    /// Success: the outputs are written.
    SD_OK = 0,
    /// The library cannot give a trustworthy answer for these inputs (a NaN in `q`, an unknown
    /// frame, a singular mass matrix, ...) or cannot build the model; outputs are untouched.
    SD_ERROR_INPUT = 1,
    /// The call itself is wrong: a NULL pointer (an array of length 0 may be NULL), a workspace
    /// made for another model, an unknown reference frame, a name that is not UTF-8, an index
    /// past the model's coordinates; outputs are untouched.
    SD_ERROR_USAGE = 2,
    /// A defect inside the library (a panic, caught at the boundary); please report the
    /// message.
    SD_ERROR_INTERNAL = 3,
}

/// Why a call failed, before it becomes a code and a message.
#[derive(Debug)]
pub(crate) enum Failure {
    /// The library's error (its `Display` is the message).
    Dynamics(DynamicsError),
    /// The model could not be built.
    Model(ModelError),
    /// A misuse of the interface, described.
    Usage(String),
}

impl From<DynamicsError> for Failure {
    fn from(e: DynamicsError) -> Self {
        Failure::Dynamics(e)
    }
}

impl From<ModelError> for Failure {
    fn from(e: ModelError) -> Self {
        Failure::Model(e)
    }
}

thread_local! {
    /// The code and message of the last failed call on this thread (NUL-terminated for C).
    static LAST_ERROR: RefCell<Option<(sd_status, CString)>> = const { RefCell::new(None) };
}

/// Stores `message` as this thread's last error, prefixed by the function that failed. An
/// interior NUL (from a name in the description) is written as `\0`. During the thread's
/// teardown (a call from a thread-local destructor, after this library's own is gone) the
/// message is not kept: the code alone says what happened.
#[cold]
fn set_last_error(status: sd_status, function: &str, message: &str) {
    let text = format!("{function}: {message}").replace('\0', "\\0");
    let text = CString::new(text).unwrap_or_default();
    let _ = LAST_ERROR.try_with(|e| *e.borrow_mut() = Some((status, text)));
}

/// The text of a caught panic's payload.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_string());
    format!("internal error (please report): {what}")
}

/// Runs `body` for the entry point `function`: `Ok` gives `SD_OK`; a failure or a panic gives
/// its code with the message stored for `sd_last_error`. Allocates only on failure.
pub(crate) fn guard(function: &str, body: impl FnOnce() -> Result<(), Failure>) -> c_int {
    let status = match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => return sd_status::SD_OK as c_int,
        // A workspace made for another model is a misuse of the interface, not bad input.
        Ok(Err(Failure::Dynamics(e @ DynamicsError::ForeignWorkspace { .. }))) => {
            (sd_status::SD_ERROR_USAGE, e.to_string())
        }
        Ok(Err(Failure::Dynamics(e))) => (sd_status::SD_ERROR_INPUT, e.to_string()),
        Ok(Err(Failure::Model(e))) => (sd_status::SD_ERROR_INPUT, e.to_string()),
        Ok(Err(Failure::Usage(m))) => (sd_status::SD_ERROR_USAGE, m),
        Err(payload) => (sd_status::SD_ERROR_INTERNAL, panic_message(&*payload)),
    };
    set_last_error(status.0, function, &status.1);
    status.0 as c_int
}

/// [`guard`] for an entry point that returns a value: `fallback` on failure or panic (the
/// message stored as by [`guard`]).
pub(crate) fn guard_value<T>(
    function: &str,
    fallback: T,
    body: impl FnOnce() -> Result<T, Failure>,
) -> T {
    let mut out = None;
    let status = guard(function, || {
        out = Some(body()?);
        Ok(())
    });
    match out {
        Some(value) if status == sd_status::SD_OK as c_int => value,
        _ => fallback,
    }
}

/// `pointer` as a reference, or a usage error naming the argument when it is NULL.
///
/// # Safety
/// A non-NULL `pointer` must point to a live `T` for `'a`.
pub(crate) unsafe fn non_null<'a, T>(pointer: *const T, argument: &str) -> Result<&'a T, Failure> {
    pointer
        .as_ref()
        .ok_or_else(|| Failure::Usage(format!("{argument} is NULL")))
}

/// The `len` values at `pointer`, or a usage error naming the argument when it is NULL (NULL is
/// accepted for no values, `len = 0`) or not aligned for an `f64`.
///
/// # Safety
/// A non-NULL `pointer` must point to `len` readable `f64`s that stay unchanged for `'a`.
pub(crate) unsafe fn input<'a>(
    pointer: *const f64,
    len: usize,
    argument: &str,
) -> Result<&'a [f64], Failure> {
    match (pointer.is_null(), len) {
        (_, 0) => Ok(&[]),
        (true, _) => Err(Failure::Usage(format!("{argument} is NULL"))),
        (false, _) => Ok(std::slice::from_raw_parts(aligned(pointer, argument)?, len)),
    }
}

/// `pointer` if it is aligned for an `f64` (8 bytes), else a usage error naming the argument:
/// a `double` array in a byte buffer at an odd offset.
fn aligned(pointer: *const f64, argument: &str) -> Result<*const f64, Failure> {
    if pointer.is_aligned() {
        Ok(pointer)
    } else {
        Err(Failure::Usage(format!(
            "{argument} is not aligned for double (8 bytes): {pointer:p}"
        )))
    }
}

/// A state's input arrays: `q` (`nq` values), `v` and `x` (`nv` each; `x` named by `x_name`:
/// `a` or `tau`), checked by [`input`] in that order.
///
/// # Safety
/// As [`input`], for each array.
pub(crate) unsafe fn state_inputs<'a>(
    model: &Model,
    q: *const f64,
    v: *const f64,
    (x, x_name): (*const f64, &str),
) -> Result<[&'a [f64]; 3], Failure> {
    let (nq, nv) = (model.nq(), model.nv());
    Ok([
        input(q, nq, "q")?,
        input(v, nv, "v")?,
        input(x, nv, x_name)?,
    ])
}

/// An output array: a usage error naming the argument when it is NULL or not aligned for an
/// `f64`, and `len > 0`.
pub(crate) fn output(pointer: *mut f64, len: usize, argument: &str) -> Result<*mut f64, Failure> {
    match (pointer.is_null(), len) {
        (_, 0) => Ok(pointer),
        (true, _) => Err(Failure::Usage(format!("{argument} is NULL"))),
        (false, _) => aligned(pointer, argument).map(|_| pointer),
    }
}

/// The message of the last call that failed on the calling thread: which function, and what
/// went wrong (naming the joint, coordinate, link or value, as the library's errors do).
/// NULL when no call has failed on this thread. Successful calls leave it as it is (check the
/// return code first); the text stays valid until the next failing call on this thread.
#[no_mangle]
pub extern "C" fn sd_last_error() -> *const c_char {
    let last = |e: &RefCell<Option<(sd_status, CString)>>| {
        e.borrow().as_ref().map_or(ptr::null(), |(_, s)| s.as_ptr())
    };
    catch_unwind(|| LAST_ERROR.try_with(last).unwrap_or(ptr::null())).unwrap_or(ptr::null())
}

/// The code of the last call that failed on the calling thread (`SD_OK` when none has): what
/// a function returning a pointer (NULL on failure) failed with. Successful calls leave it as
/// it is.
#[no_mangle]
pub extern "C" fn sd_last_status() -> c_int {
    let last = |e: &RefCell<Option<(sd_status, CString)>>| {
        e.borrow()
            .as_ref()
            .map_or(sd_status::SD_OK, |(code, _)| *code) as c_int
    };
    catch_unwind(|| {
        LAST_ERROR
            .try_with(last)
            .unwrap_or(sd_status::SD_OK as c_int)
    })
    .unwrap_or(sd_status::SD_OK as c_int)
}

/// Writes `values` to the output array `out` (checked by [`output`]).
///
/// # Safety
/// `out` must point to `values.len()` writable `f64`s (it may be an input array: the inputs
/// are no longer read).
pub(crate) unsafe fn write(out: *mut f64, values: &[f64]) {
    if !values.is_empty() {
        ptr::copy_nonoverlapping(values.as_ptr(), out, values.len());
    }
}

/// Writes `matrix` row by row (row-major) to the output array `out` (checked by [`output`]).
///
/// # Safety
/// `out` must point to `nrows · ncols` writable `f64`s.
pub(crate) unsafe fn write_row_major(out: *mut f64, matrix: &nalgebra::DMatrix<f64>) {
    let ncols = matrix.ncols();
    for r in 0..matrix.nrows() {
        for c in 0..ncols {
            out.add(r * ncols + c).write(matrix[(r, c)]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn last_error() -> String {
        let e = sd_last_error();
        assert!(!e.is_null());
        unsafe { std::ffi::CStr::from_ptr(e) }
            .to_str()
            .unwrap()
            .to_string()
    }

    #[test]
    fn a_panic_becomes_an_internal_error_with_its_message() {
        let status = guard("sd_test", || panic!("boom at joint 'j1'"));
        assert_eq!(status, sd_status::SD_ERROR_INTERNAL as c_int);
        assert_eq!(
            last_error(),
            "sd_test: internal error (please report): boom at joint 'j1'"
        );
        let value = guard_value("sd_test_value", 7usize, || {
            panic!("{}", String::from("owned"))
        });
        assert_eq!(value, 7);
        assert!(last_error().ends_with("owned"), "{}", last_error());
    }

    #[test]
    fn a_nul_in_a_message_is_written_out() {
        let status = guard("sd_test", || Err(Failure::Usage("link 'a\0b'".into())));
        assert_eq!(status, sd_status::SD_ERROR_USAGE as c_int);
        assert_eq!(last_error(), "sd_test: link 'a\\0b'");
    }
}
