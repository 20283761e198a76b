//! `sd_workspace`: the library's [`Workspace`] for one model. The library's algorithms refuse
//! a workspace made for another model (`DynamicsError::ForeignWorkspace`, a usage error here),
//! so a mismatch is an error, never a wrong answer.

use crate::model::sd_model;
use crate::status::{guard_value, non_null, non_null_mut, Failure};
use spatial_dynamics_core::{Model, Workspace};
use std::ptr;

/// Scratch buffers for one model's calls: opaque to C. Made by `sd_workspace_new`, freed by
/// `sd_workspace_free`. A workspace serves one thread at a time; give each thread its own.
pub struct sd_workspace {
    workspace: Workspace,
}

/// The model and workspace of a call, checked not NULL (the library checks that the workspace
/// was made for this model).
///
/// # Safety
/// Non-NULL pointers must point to live objects made by this library; the workspace must not
/// be in use elsewhere during the call.
pub(crate) unsafe fn checked<'a>(
    model: *const sd_model,
    workspace: *mut sd_workspace,
) -> Result<(&'a Model, &'a mut Workspace, &'a sd_model), Failure> {
    let model = non_null(model, "model")?;
    let workspace = non_null_mut(workspace, "workspace")?;
    Ok((&model.model, &mut workspace.workspace, model))
}

/// Makes the scratch buffers for `model`'s calls (NULL, with the message for `sd_last_error`,
/// when `model` is NULL). Every call after this that succeeds allocates nothing. Free it with
/// `sd_workspace_free` before its model.
#[no_mangle]
pub unsafe extern "C" fn sd_workspace_new(model: *const sd_model) -> *mut sd_workspace {
    guard_value("sd_workspace_new", ptr::null_mut(), || {
        let model = non_null(model, "model")?;
        Ok(Box::into_raw(Box::new(sd_workspace {
            workspace: Workspace::new(&model.model),
        })))
    })
}

/// Frees a workspace made by `sd_workspace_new` (NULL: does nothing).
#[no_mangle]
pub unsafe extern "C" fn sd_workspace_free(workspace: *mut sd_workspace) {
    guard_value("sd_workspace_free", (), || {
        if !workspace.is_null() {
            drop(Box::from_raw(workspace));
        }
        Ok(())
    })
}
