//! `sd_model`: a robot model built from URDF, with what the per-call functions need of it made
//! once: its coordinate names as C strings and its forward-dynamics method.

use crate::status::{guard_value, non_null, Failure};
use spatial_dynamics_core::algorithms::choose_method;
use spatial_dynamics_core::algorithms::method_choice::AUTO_TOLERANCE;
use spatial_dynamics_core::{urdf, ForwardDynamicsMethod, Model, ModelOptions};
use std::ffi::{c_char, c_int, CStr, CString};
use std::ptr;
use std::time::Duration;

/// A robot model (immutable once made): opaque to C. Made by `sd_model_from_urdf_file` or
/// `sd_model_from_urdf_string`, freed by `sd_model_free`. A freed model keeps this handle (one
/// pointer) allocated, empty, so that a later use of it, or a second free, is a usage error
/// rather than undefined behaviour.
pub struct sd_model {
    live: Option<Box<LiveModel>>,
}

/// What a model handle holds until it is freed.
pub(crate) struct LiveModel {
    pub(crate) model: Model,
    /// The method `method: auto` picks for this model ([`choose_method`]).
    pub(crate) method: ForwardDynamicsMethod,
    /// `model.v_name(i)` for each velocity coordinate.
    v_names: Vec<CString>,
}

/// Choices made when a model is built. A NULL `sd_model_options *` means all zero.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct sd_model_options {
    /// Non-zero: a floating joint between the world and the root link (7 more position
    /// coordinates `[x y z qx qy qz qw]`, 6 more velocity coordinates `[linear; angular]` in the
    /// base frame, first in `q` and `v`).
    pub floating_base: c_int,
    /// Non-zero: `<mimic>` joints are independent joints with coordinates of their own. Zero: a
    /// mimic joint follows its leader and has no coordinate.
    pub ignore_mimic: c_int,
}

/// The live model behind `model`: a usage error naming the argument when it is NULL or freed.
///
/// # Safety
/// A non-NULL `model` must have been made by this library (freed or not).
pub(crate) unsafe fn live_model<'a>(model: *const sd_model) -> Result<&'a LiveModel, Failure> {
    non_null(model, "model")?
        .live
        .as_deref()
        .ok_or_else(|| Failure::Usage("model was freed (sd_model_free)".into()))
}

impl LiveModel {
    /// The handle of a new model.
    fn handle(model: Model) -> *mut sd_model {
        Box::into_raw(Box::new(sd_model {
            live: Some(Box::new(LiveModel::new(model))),
        }))
    }

    fn new(model: Model) -> Self {
        // Errors only when no method runs on the model (a singular mass matrix, say): then
        // `aba` stays and `sd_forward_dynamics` says why.
        let method = choose_method(&model, AUTO_TOLERANCE, Duration::ZERO)
            .map_or(ForwardDynamicsMethod::Aba, |choice| choice.method);
        let v_names = (0..model.nv())
            .map(|i| CString::new(model.v_name(i).replace('\0', "\\0")).unwrap_or_default())
            .collect();
        LiveModel {
            model,
            method,
            v_names,
        }
    }
}

/// The library's options for `options` (NULL: the defaults).
unsafe fn model_options(options: *const sd_model_options) -> ModelOptions {
    let given = options.as_ref().copied().unwrap_or_default();
    ModelOptions {
        floating_base: given.floating_base != 0,
        ignore_mimic: given.ignore_mimic != 0,
        ..ModelOptions::default()
    }
}

/// A C string argument as UTF-8 text, without copying.
///
/// # Safety
/// A non-NULL `text` must be NUL-terminated and stay unchanged for `'a`.
pub(crate) unsafe fn text<'a>(text: *const c_char, argument: &str) -> Result<&'a str, Failure> {
    let text = non_null(text, argument)?;
    CStr::from_ptr(text)
        .to_str()
        .map_err(|e| Failure::Usage(format!("{argument} is not UTF-8 text: {e}")))
}

/// A C string argument as a file path: its bytes as they are (a Unix path need not be UTF-8).
///
/// # Safety
/// As [`text`].
#[cfg(unix)]
unsafe fn path<'a>(path: *const c_char, argument: &str) -> Result<&'a std::path::Path, Failure> {
    use std::os::unix::ffi::OsStrExt;
    let path = non_null(path, argument)?;
    Ok(std::path::Path::new(std::ffi::OsStr::from_bytes(
        CStr::from_ptr(path).to_bytes(),
    )))
}

/// A C string argument as a file path (UTF-8 where paths are text).
///
/// # Safety
/// As [`text`].
#[cfg(not(unix))]
unsafe fn path<'a>(path: *const c_char, argument: &str) -> Result<&'a std::path::Path, Failure> {
    text(path, argument).map(std::path::Path::new)
}

/// Builds a model from the URDF file at `path` (NUL-terminated; on Unix any bytes, elsewhere
/// UTF-8). `options` may be NULL
/// (fixed base, mimic joints followed). Chooses the model's forward-dynamics method now (the
/// one `method: auto` picks: the fewest floating-point operations among the methods agreeing
/// with the articulated-body algorithm, one that handles mimic joints when there are some),
/// which takes a few milliseconds: make models outside a real-time loop.
///
/// Returns NULL on error (`sd_last_error` says why: the file, the element or joint at fault).
/// Free the model with `sd_model_free`, after every workspace made for it.
#[no_mangle]
pub unsafe extern "C" fn sd_model_from_urdf_file(
    file: *const c_char,
    options: *const sd_model_options,
) -> *mut sd_model {
    guard_value("sd_model_from_urdf_file", ptr::null_mut(), || {
        let model = urdf::model_from_file(path(file, "path")?, &model_options(options))?;
        Ok(LiveModel::handle(model))
    })
}

/// Builds a model from URDF text (`urdf`, NUL-terminated, UTF-8); as `sd_model_from_urdf_file`
/// otherwise. Returns NULL on error (`sd_last_error` says why).
#[no_mangle]
pub unsafe extern "C" fn sd_model_from_urdf_string(
    urdf: *const c_char,
    options: *const sd_model_options,
) -> *mut sd_model {
    guard_value("sd_model_from_urdf_string", ptr::null_mut(), || {
        let model = urdf::model_from_str(text(urdf, "urdf")?, &model_options(options))?;
        Ok(LiveModel::handle(model))
    })
}

/// Frees a model made by `sd_model_from_urdf_file` or `sd_model_from_urdf_string` (NULL, or a
/// model already freed: does nothing). The handle itself stays allocated (one pointer), so that
/// a call given it afterwards fails with `SD_ERROR_USAGE`; its workspaces are refused from then
/// on. Free it while no other thread uses it.
#[no_mangle]
pub unsafe extern "C" fn sd_model_free(model: *mut sd_model) {
    guard_value("sd_model_free", (), || {
        if let Some(handle) = model.as_mut() {
            drop(handle.live.take());
        }
        Ok(())
    })
}

/// Number of position coordinates `nq`: the length of every `q` array (0 for NULL or freed).
#[no_mangle]
pub unsafe extern "C" fn sd_model_nq(model: *const sd_model) -> usize {
    guard_value("sd_model_nq", 0, || Ok(live_model(model)?.model.nq()))
}

/// Number of velocity coordinates `nv`: the length of every `v`, `a`, `tau`, `qdd` and `g`
/// array, the size of the `nv × nv` mass matrix and the number of columns of a `6 × nv`
/// Jacobian (0 for NULL or freed).
#[no_mangle]
pub unsafe extern "C" fn sd_model_nv(model: *const sd_model) -> usize {
    guard_value("sd_model_nv", 0, || Ok(live_model(model)?.model.nv()))
}

/// The name of velocity coordinate `index` (`0 ≤ index < nv`), in the order of `v`: the joint's
/// name, with the component for a joint of several coordinates (`base[2]`). Owned by the model
/// (valid until `sd_model_free`). NULL for an index out of range or a NULL or freed model (with
/// the message for `sd_last_error`).
#[no_mangle]
pub unsafe extern "C" fn sd_model_v_name(model: *const sd_model, index: usize) -> *const c_char {
    guard_value("sd_model_v_name", ptr::null(), || {
        let model = live_model(model)?;
        let name = model.v_names.get(index).ok_or_else(|| {
            Failure::Usage(format!(
                "index {index} is out of range: the model has {} velocity coordinates",
                model.v_names.len()
            ))
        })?;
        Ok(name.as_ptr())
    })
}

/// The forward-dynamics method `sd_forward_dynamics` uses for this model, chosen when it was
/// made: `"aba"`, `"crba"` or `"rnea_columns"` (a static string; NULL for a NULL or freed
/// model).
#[no_mangle]
pub unsafe extern "C" fn sd_model_forward_dynamics_method(model: *const sd_model) -> *const c_char {
    guard_value("sd_model_forward_dynamics_method", ptr::null(), || {
        Ok(match live_model(model)?.method {
            ForwardDynamicsMethod::Aba => c"aba",
            ForwardDynamicsMethod::Crba => c"crba",
            ForwardDynamicsMethod::RneaColumns => c"rnea_columns",
        }
        .as_ptr())
    })
}
