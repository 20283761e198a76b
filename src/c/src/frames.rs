//! Frame Jacobians: the library's [`frame_jacobian`] over C arrays, the frame named by its URDF
//! link and looked up without allocating.

use crate::model::text;
use crate::sd_model;
use crate::status::{guard, input, output, write_row_major, Failure};
use crate::workspace::{checked, sd_workspace};
use spatial_dynamics_core::algorithms::{find_frame, frame_jacobian, ReferenceFrame};
use std::ffi::{c_char, c_int};

/// The frame a Jacobian's twist is expressed in, with Pinocchio's meaning
/// (`pinocchio::ReferenceFrame`), passed as an `int`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum sd_reference_frame {
    /// World axes, about the world origin (the spatial twist): linear rows are the velocity of
    /// the body-fixed point at the world origin.
    SD_WORLD = 0,
    /// The link's axes, at the link's origin (the body twist).
    SD_LOCAL = 1,
    /// World axes, at the link's origin: linear rows are the velocity of the link origin.
    SD_LOCAL_WORLD_ALIGNED = 2,
}

/// The library's reference frame for the C value `reference`.
fn reference_frame(reference: c_int) -> Result<ReferenceFrame, Failure> {
    const WORLD: c_int = sd_reference_frame::SD_WORLD as c_int;
    const LOCAL: c_int = sd_reference_frame::SD_LOCAL as c_int;
    const ALIGNED: c_int = sd_reference_frame::SD_LOCAL_WORLD_ALIGNED as c_int;
    match reference {
        WORLD => Ok(ReferenceFrame::World),
        LOCAL => Ok(ReferenceFrame::Local),
        ALIGNED => Ok(ReferenceFrame::LocalWorldAligned),
        _ => Err(Failure::Usage(format!(
            "reference {reference} is not SD_WORLD (0), SD_LOCAL (1) or SD_LOCAL_WORLD_ALIGNED (2)"
        ))),
    }
}

/// The Jacobian `J` of the frame of URDF link `frame` (NUL-terminated) at `q`: the twist of the
/// frame is `[linear; angular] = J v`. `6 × nv`, row-major (`j[r·nv + c]`), rows 0–2 the linear
/// velocity (m/s per unit of `v`), rows 3–5 the angular velocity (rad/s per unit of `v`), in
/// `reference` (`SD_WORLD`, `SD_LOCAL` or `SD_LOCAL_WORLD_ALIGNED`, as Pinocchio's
/// `getFrameJacobian`). Any link of the description is a frame, fused by a fixed joint or
/// not; a link fixed to the world has a zero Jacobian. `q`: `nq` values; `j`: `6·nv`. Returns 0,
/// or non-zero with `sd_last_error` naming the unknown link (and listing the model's) or the
/// coordinate at fault.
#[no_mangle]
pub unsafe extern "C" fn sd_frame_jacobian(
    model: *const sd_model,
    workspace: *mut sd_workspace,
    q: *const f64,
    frame: *const c_char,
    reference: c_int,
    j: *mut f64,
) -> c_int {
    guard("sd_frame_jacobian", || {
        let (model, mut ws, _) = checked(model, workspace)?;
        let q = input(q, model.nq(), "q")?;
        let frame = find_frame(model, text(frame, "frame")?)?;
        let reference = reference_frame(reference)?;
        let j = output(j, 6 * model.nv(), "j")?;
        write_row_major(j, frame_jacobian(model, &mut ws, q, &frame, reference)?);
        Ok(())
    })
}
