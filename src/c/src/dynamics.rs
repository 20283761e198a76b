//! Inverse dynamics, gravity, forward dynamics and the mass matrix: the library's
//! [`rnea`], [`gravity`], [`forward_dynamics`] and [`crba`] over C arrays.
//!
//! Every function takes the model, a workspace made for it, input arrays of the lengths the
//! model gives (`nq` for `q`, `nv` for velocities, accelerations and efforts) and output
//! arrays, written only on success (an output may be one of the inputs). Efforts are in N·m
//! for a revolute coordinate and N for a prismatic one (a floating base's: force then torque,
//! base frame); accelerations in rad/s² or m/s².

use crate::sd_model;
use crate::status::{guard, input, output, state_inputs, write, write_row_major};
use crate::workspace::{checked, sd_workspace};
use spatial_dynamics_core::algorithms::{crba, forward_dynamics, gravity, rnea};
use spatial_dynamics_core::Externals;
use std::ffi::c_int;

/// Inverse dynamics (recursive Newton–Euler): `tau = M(q) a + C(q, v) + g(q)`, the efforts that
/// give the robot acceleration `a` at position `q` and velocity `v` under gravity (base at
/// rest in an inertial frame, no external forces). `q`: `nq` values; `v`, `a`, `tau`: `nv`.
/// Returns 0, or non-zero with `sd_last_error` naming the coordinate at fault (a NaN, a
/// quaternion of norm zero, an overflow).
#[no_mangle]
pub unsafe extern "C" fn sd_rnea(
    model: *const sd_model,
    workspace: *mut sd_workspace,
    q: *const f64,
    v: *const f64,
    a: *const f64,
    tau: *mut f64,
) -> c_int {
    guard("sd_rnea", || {
        let (model, mut ws, _) = checked(model, workspace)?;
        let [q, v, a] = state_inputs(model, q, v, (a, "a"))?;
        let tau = output(tau, model.nv(), "tau")?;
        write(tau, rnea(model, &mut ws, q, v, a)?);
        Ok(())
    })
}

/// Generalized gravity `g = g(q)`: the efforts that hold the robot still at `q` against
/// gravity (gravity compensation). `q`: `nq` values; `g`: `nv`. Returns 0, or non-zero with
/// `sd_last_error` naming the coordinate at fault.
#[no_mangle]
pub unsafe extern "C" fn sd_gravity(
    model: *const sd_model,
    workspace: *mut sd_workspace,
    q: *const f64,
    g: *mut f64,
) -> c_int {
    guard("sd_gravity", || {
        let (model, mut ws, _) = checked(model, workspace)?;
        let q = input(q, model.nq(), "q")?;
        let g = output(g, model.nv(), "g")?;
        write(g, gravity(model, &mut ws, q)?);
        Ok(())
    })
}

/// Forward dynamics: `qdd = M(q)⁻¹ (tau − C(q, v) − g(q))`, the acceleration the efforts `tau`
/// give the robot at `q`, `v` (base at rest in an inertial frame, no external forces), by the
/// method chosen for the model when it was made (`sd_model_forward_dynamics_method`). `q`: `nq`
/// values; `v`, `tau`, `qdd`: `nv`. Returns 0, or non-zero with `sd_last_error` naming the
/// coordinate or joint at fault (a NaN, a singular mass matrix at a massless joint).
#[no_mangle]
pub unsafe extern "C" fn sd_forward_dynamics(
    model: *const sd_model,
    workspace: *mut sd_workspace,
    q: *const f64,
    v: *const f64,
    tau: *const f64,
    qdd: *mut f64,
) -> c_int {
    guard("sd_forward_dynamics", || {
        let (model, mut ws, made) = checked(model, workspace)?;
        let [q, v, tau] = state_inputs(model, q, v, (tau, "tau"))?;
        let qdd = output(qdd, model.nv(), "qdd")?;
        write(
            qdd,
            forward_dynamics(model, &mut ws, q, v, tau, made.method, &Externals::none())?,
        );
        Ok(())
    })
}

/// The joint-space mass matrix `M(q)` (composite rigid-body algorithm), `nv × nv`, symmetric,
/// row-major: `m[r·nv + c] = M_rc`, in kg·m² between revolute coordinates, kg between prismatic
/// ones, kg·m between the two. `q`: `nq` values; `m`: `nv·nv`. Returns 0, or non-zero with
/// `sd_last_error` naming the coordinate at fault.
#[no_mangle]
pub unsafe extern "C" fn sd_mass_matrix(
    model: *const sd_model,
    workspace: *mut sd_workspace,
    q: *const f64,
    m: *mut f64,
) -> c_int {
    guard("sd_mass_matrix", || {
        let (model, mut ws, _) = checked(model, workspace)?;
        let q = input(q, model.nq(), "q")?;
        let m = output(m, model.nv() * model.nv(), "m")?;
        write_row_major(m, crba(model, &mut ws, q)?);
        Ok(())
    })
}
