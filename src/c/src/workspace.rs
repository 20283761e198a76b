//! `sd_workspace`: the library's [`Workspace`] for one model. The library's algorithms refuse
//! a workspace made for another model (`DynamicsError::ForeignWorkspace`, a usage error here),
//! so a mismatch is an error, never a wrong answer; a workspace used by two calls at once is
//! refused too, never shared.

use crate::model::{live_model, sd_model, LiveModel};
use crate::status::{guard_value, non_null, Failure};
use spatial_dynamics_core::{Model, Workspace};
use std::cell::UnsafeCell;
use std::ops::{Deref, DerefMut};
use std::ptr;
use std::sync::atomic::{AtomicBool, Ordering};

/// Scratch buffers for one model's calls: opaque to C. Made by `sd_workspace_new`, freed by
/// `sd_workspace_free`. A workspace serves one call at a time: a call while another uses it (on
/// another thread) fails with `SD_ERROR_USAGE`; give each thread its own. A freed workspace
/// keeps this handle allocated, empty, so that a later use of it, or a second free, is a usage
/// error rather than undefined behaviour.
pub struct sd_workspace {
    /// Set while a call uses the workspace.
    busy: AtomicBool,
    /// `None` once freed; written only by the call holding `busy`.
    workspace: UnsafeCell<Option<Box<Workspace>>>,
}

impl sd_workspace {
    /// Takes `busy` if no call holds it: whether this caller now holds it.
    fn acquire(&self) -> bool {
        self.busy
            .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
            .is_ok()
    }
}

/// The workspace of one call, released when dropped (also when the call panics).
pub(crate) struct InUse<'a> {
    busy: &'a AtomicBool,
    workspace: &'a mut Workspace,
}

impl Deref for InUse<'_> {
    type Target = Workspace;
    fn deref(&self) -> &Workspace {
        self.workspace
    }
}

impl DerefMut for InUse<'_> {
    fn deref_mut(&mut self) -> &mut Workspace {
        self.workspace
    }
}

impl Drop for InUse<'_> {
    fn drop(&mut self) {
        self.busy.store(false, Ordering::Release);
    }
}

/// `workspace` taken for one call: a usage error naming it when it is NULL, freed, or in use by
/// another call.
///
/// # Safety
/// A non-NULL `workspace` must have been made by this library (freed or not).
unsafe fn take<'a>(workspace: *const sd_workspace) -> Result<InUse<'a>, Failure> {
    let handle = non_null(workspace, "workspace")?;
    if !handle.acquire() {
        return Err(Failure::Usage(
            "workspace is in use by another call (give each thread its own workspace)".into(),
        ));
    }
    let busy = &handle.busy;
    // Holding `busy`, this call alone reaches the contents.
    match (*handle.workspace.get()).as_deref_mut() {
        Some(workspace) => Ok(InUse { busy, workspace }),
        None => {
            busy.store(false, Ordering::Release);
            Err(Failure::Usage(
                "workspace was freed (sd_workspace_free)".into(),
            ))
        }
    }
}

/// The model and workspace of a call, checked (not NULL, not freed, the workspace not in use;
/// the library checks that the workspace was made for this model).
///
/// # Safety
/// Non-NULL pointers must point to objects made by this library (freed or not).
pub(crate) unsafe fn checked<'a>(
    model: *const sd_model,
    workspace: *mut sd_workspace,
) -> Result<(&'a Model, InUse<'a>, &'a LiveModel), Failure> {
    let model = live_model(model)?;
    Ok((&model.model, take(workspace)?, model))
}

/// Makes the scratch buffers for `model`'s calls (NULL, with the message for `sd_last_error`,
/// when `model` is NULL or freed). Every call after this that succeeds allocates nothing. Free
/// it with `sd_workspace_free` before its model.
#[no_mangle]
pub unsafe extern "C" fn sd_workspace_new(model: *const sd_model) -> *mut sd_workspace {
    guard_value("sd_workspace_new", ptr::null_mut(), || {
        let model = live_model(model)?;
        Ok(Box::into_raw(Box::new(sd_workspace {
            busy: AtomicBool::new(false),
            workspace: UnsafeCell::new(Some(Box::new(Workspace::new(&model.model)))),
        })))
    })
}

/// Frees a workspace made by `sd_workspace_new` (NULL, or a workspace already freed: does
/// nothing). The handle itself stays allocated (a few bytes), so that a call given it afterwards
/// fails with `SD_ERROR_USAGE`. A workspace in use by a call on another thread is not freed
/// (`sd_last_error` says so).
#[no_mangle]
pub unsafe extern "C" fn sd_workspace_free(workspace: *mut sd_workspace) {
    guard_value("sd_workspace_free", (), || {
        let Some(handle) = workspace.as_ref() else {
            return Ok(());
        };
        if !handle.acquire() {
            return Err(Failure::Usage(
                "workspace is in use by another call: not freed".into(),
            ));
        }
        // Holding `busy`: nothing else reaches the contents (`None` once freed).
        drop((*handle.workspace.get()).take());
        handle.busy.store(false, Ordering::Release);
        Ok(())
    })
}
