//! Arguments as float64 rows, in two steps. [`Arg::inspect`] reads an argument's dtype and
//! shape without converting it: a numpy array as it is, anything else (a list, a tuple, an
//! object with `__array__`) through `numpy.asarray`. Only real numbers are taken (dtype kinds
//! float, signed and unsigned integer): anything else (bool, complex, strings, bytes, dates,
//! objects, `None`) is a `TypeError` naming the argument, and so is a masked array
//! (`numpy.ma.MaskedArray`), whose mask the computation could not honour, also as an item of a
//! list or tuple (`name[i]`). A 1-D argument is one
//! state, a 2-D one N states (a row each); any other shape is a `DynamicsError` naming the
//! argument and the length the model needs. [`Arg::rows`] then reads the values: a
//! C-contiguous, aligned, native float64 array is borrowed as it is, anything else is copied
//! once into a new float64 array. Values read with the GIL released must be private (another
//! Python thread could write a shared array meanwhile): a borrowed array that other code can
//! reach is then copied, with the GIL held. Exceptions other than `ValueError` raised by numpy
//! on the way (`MemoryError`, `KeyboardInterrupt`) propagate unchanged.

use crate::batch::empty;
use crate::errors::error;
use numpy::{
    PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{IntoPyDict, PyList, PyTuple, PyType};

/// One argument whose dtype and shape were checked, not yet read as float64.
pub struct Arg<'py> {
    name: String,
    array: Bound<'py, PyUntypedArray>,
    /// `None` for one state (1-D), `Some(n)` for `n` rows (2-D).
    pub states: Option<usize>,
    /// Whether `array` was made by `numpy.asarray` from a list or tuple: a new array that no
    /// other code refers to.
    fresh: bool,
}

impl<'py> Arg<'py> {
    /// `value`, the argument called `name`, as states of `len` values each.
    pub fn inspect(value: &Bound<'py, PyAny>, name: &str, len: usize) -> PyResult<Self> {
        let (array, fresh) = match value.cast::<PyUntypedArray>() {
            Ok(array) => {
                if !value.is_exact_instance_of::<PyUntypedArray>() && is_masked(value)? {
                    return Err(PyTypeError::new_err(format!(
                        "{name} is a masked array (numpy.ma.MaskedArray): masked arrays are not \
                         taken, their mask would be ignored; pass {name}.filled(value) or \
                         {name}.data"
                    )));
                }
                (array.clone(), false)
            }
            Err(_) => {
                let fresh = value.is_exact_instance_of::<PyList>()
                    || value.is_exact_instance_of::<PyTuple>();
                if fresh {
                    refuse_masked_rows(value, name)?;
                }
                (as_array(value, name)?, fresh)
            }
        };
        let kind = array.dtype().kind();
        if !matches!(kind, b'f' | b'i' | b'u') {
            return Err(not_real(value, &array, name));
        }
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
        Ok(Arg {
            name: name.to_string(),
            array,
            states,
            fresh,
        })
    }

    /// The values as float64 rows: borrowed when the array is C-contiguous, aligned and native
    /// float64, otherwise copied into a new array. With `private`, for values read with the GIL
    /// released, an array that would be borrowed is copied unless `numpy.asarray` made it from
    /// a list or tuple: no Python thread can then write the values being read. Either way, the
    /// values are copied once at most.
    pub fn rows(&self, private: bool) -> PyResult<Rows<'py>> {
        if let Ok(floats) = self.array.cast::<PyArrayDyn<f64>>() {
            if floats.is_c_contiguous() && floats.is_aligned() {
                if let Ok(borrowed) = floats.try_readonly() {
                    if private && !self.fresh {
                        return self.own(&borrowed);
                    }
                    return Ok(Rows::Array(borrowed));
                }
            }
        }
        self.copy()
    }

    /// The values of `borrowed` copied with the GIL held (no Python code writes them
    /// meanwhile): up to [`SMALL_COPY`] values into a `Vec`, more into a new array by
    /// `numpy.empty`, which keeps the GIL and asks for huge pages (most of a large copy's time
    /// is the page faults of its new memory); a size numpy cannot allocate is its `MemoryError`.
    fn own(&self, borrowed: &PyReadonlyArrayDyn<'py, f64>) -> PyResult<Rows<'py>> {
        let values = borrowed
            .as_slice()
            .map_err(|_| error(format!("{} is not contiguous", self.name)))?;
        if values.len() <= SMALL_COPY {
            return Ok(Rows::Owned(values.to_vec()));
        }
        let copy = empty(self.array.py(), self.array.shape())?;
        copy.try_readwrite()
            .map_err(|e| error(format!("a copy of {} cannot be written: {e}", self.name)))?
            .as_slice_mut()
            .map_err(|_| error(format!("a copy of {} is not contiguous", self.name)))?
            .copy_from_slice(values);
        let array = copy
            .try_readonly()
            .map_err(|e| error(format!("a copy of {} cannot be read: {e}", self.name)))?;
        Ok(Rows::Array(array))
    }

    /// `numpy.array(self, dtype=float64, order="C")`: a new array, contiguous and aligned.
    #[cold]
    fn copy(&self) -> PyResult<Rows<'py>> {
        static ARRAY: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
        static FLOAT64: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
        let py = self.array.py();
        let float64 = FLOAT64.import(py, "numpy", "float64")?;
        let copied = ARRAY
            .import(py, "numpy", "array")?
            .call(
                (&self.array, float64),
                Some(&[("order", "C")].into_py_dict(py)?),
            )
            .map_err(|e| relabel(py, e, &self.name))?;
        let array = copied
            .cast_into::<PyArrayDyn<f64>>()
            .map_err(|_| error(format!("{} could not be read as float64 values", self.name)))?;
        let borrowed = array
            .try_readonly()
            .map_err(|e| error(format!("{} cannot be read: {e}", self.name)))?;
        Ok(Rows::Array(borrowed))
    }
}

/// The most values [`Arg::rows`] copies into a `Vec` (256 KiB): a numpy call costs more than
/// such a copy, whose memory the allocator has at hand.
const SMALL_COPY: usize = 1 << 15;

/// One argument's values, float64, C-contiguous and aligned.
pub enum Rows<'py> {
    /// A numpy array: the argument itself, or a new array it was copied or converted into.
    Array(PyReadonlyArrayDyn<'py, f64>),
    /// A copy of a small argument's values.
    Owned(Vec<f64>),
}

impl Rows<'_> {
    /// Every value, row after row.
    pub fn values(&self) -> PyResult<&[f64]> {
        match self {
            Rows::Array(array) => array
                .as_slice()
                .map_err(|_| error("an argument's float64 copy is not contiguous")),
            Rows::Owned(values) => Ok(values),
        }
    }
}

/// Whether `value` is a numpy masked array (`numpy.ma.MaskedArray` or a subclass).
#[cold]
fn is_masked(value: &Bound<'_, PyAny>) -> PyResult<bool> {
    match masked_array_type(value.py())? {
        Some(masked) => value.is_instance(masked.bind(value.py())),
        None => Ok(false),
    }
}

/// `numpy.ma.MaskedArray`, or `None` while `numpy.ma` is not imported: no masked array exists
/// before (numpy does not import it by itself), so this does not import it; it looks in
/// `sys.modules`.
fn masked_array_type(py: Python<'_>) -> PyResult<Option<&'static Py<PyType>>> {
    static MASKED_ARRAY: PyOnceLock<Py<PyType>> = PyOnceLock::new();
    if let Some(masked) = MASKED_ARRAY.get(py) {
        return Ok(Some(masked));
    }
    let modules = py.import("sys")?.getattr("modules")?;
    let Ok(ma) = modules.get_item("numpy.ma") else {
        return Ok(None);
    };
    let masked = ma.getattr("MaskedArray")?.cast_into::<PyType>()?;
    Ok(Some(MASKED_ARRAY.get_or_init(py, || masked.unbind())))
}

/// A `TypeError` naming `{name}[i]` for the first item of the list or tuple `value` that is a
/// masked array (a row of N states, or `numpy.ma.masked` among the values): `numpy.asarray`
/// would read the values under its mask (a masked value as NaN, a masked row's hidden data as
/// it is).
fn refuse_masked_rows(value: &Bound<'_, PyAny>, name: &str) -> PyResult<()> {
    let Some(masked) = masked_array_type(value.py())? else {
        return Ok(());
    };
    let masked = masked.bind(value.py());
    for (i, item) in value.try_iter()?.enumerate() {
        if item?.is_instance(masked)? {
            return Err(PyTypeError::new_err(format!(
                "{name}[{i}] is a masked array (numpy.ma.MaskedArray): masked arrays are not \
                 taken, their mask would be ignored; pass {name}[{i}].filled(value) or \
                 {name}[{i}].data"
            )));
        }
    }
    Ok(())
}

/// `numpy.asarray(value)`: the array numpy reads from a list, tuple or other array-like. A
/// `ValueError` (ragged rows) becomes a `DynamicsError` naming the argument; other exceptions
/// propagate unchanged.
#[cold]
fn as_array<'py>(value: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    static AS_ARRAY: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    let py = value.py();
    let array = AS_ARRAY
        .import(py, "numpy", "asarray")?
        .call1((value,))
        .map_err(|e| relabel(py, e, name))?;
    array.cast_into::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be real numbers (a float or integer array, or a sequence of them)"
        ))
    })
}

/// `e` raised by numpy while reading the argument `name`: a `ValueError` becomes a
/// `DynamicsError` naming the argument (with `e` as its cause), anything else is `e` itself.
fn relabel(py: Python<'_>, e: PyErr, name: &str) -> PyErr {
    if e.is_instance_of::<PyValueError>(py) {
        let relabelled = error(format!("{name} is not an array of numbers: {e}"));
        relabelled.set_cause(py, Some(e));
        relabelled
    } else {
        e
    }
}

/// The `TypeError` of an argument that is not real numbers: its dtype, and for a value that is
/// not a numpy array, its Python type too.
#[cold]
fn not_real(value: &Bound<'_, PyAny>, array: &Bound<'_, PyUntypedArray>, name: &str) -> PyErr {
    let dtype = array
        .dtype()
        .str()
        .map_or_else(|_| "?".to_string(), |s| s.to_string());
    let got = if value.is_instance_of::<PyUntypedArray>() {
        format!("an array of dtype {dtype}")
    } else {
        let type_name = value
            .get_type()
            .name()
            .map_or_else(|_| "?".to_string(), |s| s.to_string());
        format!("{type_name} (read by numpy as dtype {dtype})")
    };
    PyTypeError::new_err(format!(
        "{name} must be real numbers (a float or integer array, or a sequence of them), not {got}"
    ))
}

/// A shape as Python prints it: `()`, `(3,)`, `(2, 3)`.
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
pub fn states_of(args: &[Arg<'_>]) -> PyResult<Option<usize>> {
    let Some(first) = args.first() else {
        return Ok(None);
    };
    for arg in &args[1..] {
        if arg.states != first.states {
            let describe = |s: Option<usize>| match s {
                None => "one state (1-D)".to_string(),
                Some(n) => format!("{n} states (2-D)"),
            };
            return Err(error(format!(
                "{} holds {}, {} {}: give every argument as 1-D, or every one as 2-D with the same rows",
                arg.name,
                describe(arg.states),
                first.name,
                describe(first.states)
            )));
        }
    }
    Ok(first.states)
}
