//! The analytical derivatives of inverse and forward dynamics: the library's
//! [`rnea_derivatives`] and [`aba_derivatives`] over C arrays.
//!
//! Each output is an `nv × nv` matrix, row-major (`out[r·nv + c]`: row `r` the derivative of
//! coordinate `r`'s effort or acceleration, column `c` along velocity coordinate `c`), written
//! only on success. Derivatives along `q` are taken on the tangent of the configuration space
//! (`q ⊕ ε e_c`, the velocity coordinates' order), as Pinocchio's are; units are those of the
//! quantity over those of the coordinate.

use crate::sd_model;
use crate::status::{guard, output, state_inputs, write_row_major};
use crate::workspace::{checked, sd_workspace};
use spatial_dynamics_core::algorithms::{aba_derivatives, rnea_derivatives};
use spatial_dynamics_core::Externals;
use std::ffi::c_int;

/// The derivatives of inverse dynamics `tau = RNEA(q, v, a)` (gravity, no external forces,
/// base at rest): `dtau_dq = ∂tau/∂q`, `dtau_dv = ∂tau/∂v` and `m = ∂tau/∂a = M(q)`, the mass
/// matrix (full, symmetric). `q`: `nq` values; `v`, `a`: `nv`; each output `nv·nv`,
/// row-major. Returns 0, or non-zero with `sd_last_error` naming the coordinate at fault.
#[no_mangle]
pub unsafe extern "C" fn sd_rnea_derivatives(
    model: *const sd_model,
    workspace: *mut sd_workspace,
    q: *const f64,
    v: *const f64,
    a: *const f64,
    dtau_dq: *mut f64,
    dtau_dv: *mut f64,
    m: *mut f64,
) -> c_int {
    guard("sd_rnea_derivatives", || {
        let (model, mut ws, _) = checked(model, workspace)?;
        let [q, v, a] = state_inputs(model, q, v, (a, "a"))?;
        let nv = model.nv();
        let dtau_dq = output(dtau_dq, nv * nv, "dtau_dq")?;
        let dtau_dv = output(dtau_dv, nv * nv, "dtau_dv")?;
        let m = output(m, nv * nv, "m")?;
        let d = rnea_derivatives(model, &mut ws, q, v, a)?;
        write_row_major(dtau_dq, d.dtau_dq);
        write_row_major(dtau_dv, d.dtau_dv);
        write_row_major(m, d.mass_matrix);
        Ok(())
    })
}

/// The derivatives of forward dynamics `qdd = FD(q, v, tau)` (gravity, no external forces,
/// base at rest): `ddq_dq = ∂qdd/∂q`, `ddq_dv = ∂qdd/∂v` and `minv = ∂qdd/∂tau = M(q)⁻¹`
/// (full, symmetric). `q`: `nq` values; `v`, `tau`: `nv`; each output `nv·nv`, row-major.
/// Returns 0, or non-zero with `sd_last_error` naming the coordinate or joint at fault (a NaN,
/// a singular mass matrix).
#[no_mangle]
pub unsafe extern "C" fn sd_aba_derivatives(
    model: *const sd_model,
    workspace: *mut sd_workspace,
    q: *const f64,
    v: *const f64,
    tau: *const f64,
    ddq_dq: *mut f64,
    ddq_dv: *mut f64,
    minv: *mut f64,
) -> c_int {
    guard("sd_aba_derivatives", || {
        let (model, mut ws, _) = checked(model, workspace)?;
        let [q, v, tau] = state_inputs(model, q, v, (tau, "tau"))?;
        let nv = model.nv();
        let ddq_dq = output(ddq_dq, nv * nv, "ddq_dq")?;
        let ddq_dv = output(ddq_dv, nv * nv, "ddq_dv")?;
        let minv = output(minv, nv * nv, "minv")?;
        let d = aba_derivatives(model, &mut ws, q, v, tau, &Externals::none())?;
        write_row_major(ddq_dq, d.ddq_dq);
        write_row_major(ddq_dv, d.ddq_dv);
        write_row_major(minv, d.minv);
        Ok(())
    })
}
