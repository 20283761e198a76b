//! Forward dynamics from n+1 inverse-dynamics calls (the handout's §2, after Walker and Orin):
//!
//! ```text
//! C   = RNEA(q, q̇, 0)                 (9)
//! H_k = RNEA(q, q̇, e_k) − C           (11), for each coordinate k
//! H q̈ = τ − C                          (6), solved by Cholesky
//! ```
//!
//! Each RNEA call is a complete inverse-dynamics evaluation, as the method prescribes, so it costs
//! O(n²) and serves as the reference the faster methods are measured against.

use super::cholesky::{cholesky_factor, cholesky_solve};
use super::kinematics::update_joints;
use super::rnea::rnea_passes;
use super::validate::{check_forward_inputs, check_result};
use super::Externals;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;

/// `q̈ = FD(q, q̇, τ)` into `ws.qdd()`; leaves `H` in `ws.mass_matrix()`.
pub fn rnea_columns<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    check_forward_inputs(model, ws, q, v, tau, ext)?;
    inverse_dynamics(model, ws, q, v, None, ext);
    ws.bias.copy_from(&ws.tau);
    ws.unit.fill(0.0);
    for k in 0..model.nv {
        ws.unit[k] = 1.0;
        let unit = std::mem::take(&mut ws.unit);
        inverse_dynamics(model, ws, q, v, Some(unit.as_slice()), ext);
        ws.unit = unit;
        ws.unit[k] = 0.0;
        for r in 0..model.nv {
            ws.mass_matrix[(r, k)] = ws.tau[r] - ws.bias[r];
        }
    }
    // Outside the tree's pattern a finite entry is exactly zero (the same operations give τ
    // and C there), as the workspace's other writers expect; an overflow leaves NaN
    // everywhere, so the matrix is cleared before the error is returned.
    if let Some(i) = ws.mass_matrix.iter().position(|x| !x.is_finite()) {
        ws.mass_matrix.as_mut_slice().fill(0.0);
        return Err(DynamicsError::NonFiniteResult {
            quantity: "mass matrix",
            coordinate: model.v_name(i / model.nv),
        });
    }
    cholesky_factor(model, &ws.mass_matrix, &mut ws.factor)?;
    ws.qdd.copy_from_slice(tau);
    ws.qdd -= &ws.bias;
    cholesky_solve(&ws.factor, &mut ws.qdd);
    check_result(model, "acceleration", ws.qdd.as_slice())?;
    Ok(ws.qdd.as_slice())
}

/// One complete RNEA call on validated inputs (joint transforms included).
fn inverse_dynamics(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
    a: Option<&[f64]>,
    ext: &Externals<'_>,
) {
    update_joints(model, ws, q);
    rnea_passes(model, ws, Some(v), a, ext);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::MIMIC_GRIPPER_URDF;
    use crate::{algorithms::crba::crba, urdf, ModelOptions};

    /// A refused call leaves nothing behind that a later algorithm reads: CRBA, which writes
    /// only the tree's pattern, still gives the mass matrix a fresh workspace gives.
    #[test]
    fn an_overflow_leaves_the_mass_matrix_usable() {
        let options = ModelOptions {
            ignore_mimic: true,
            ..ModelOptions::default()
        };
        let model = urdf::model_from_str(MIMIC_GRIPPER_URDF, &options).unwrap();
        let (nq, nv) = (model.nq(), model.nv());
        let q: Vec<f64> = (0..nq).map(|k| 0.1 * k as f64).collect();
        let mut huge = vec![0.0; nv];
        huge[0] = 1e300;
        let mut ws = Workspace::new(&model);
        let err = rnea_columns(
            &model,
            &mut ws,
            &q,
            &huge,
            &vec![0.0; nv],
            &Externals::none(),
        )
        .unwrap_err();
        assert!(
            matches!(err, DynamicsError::NonFiniteResult { .. }),
            "{err}"
        );
        let after = crba(&model, &mut ws, &q).unwrap().clone();
        let fresh = crba(&model, &mut Workspace::new(&model), &q)
            .unwrap()
            .clone();
        assert!(after.iter().all(|x| x.is_finite()), "{after}");
        assert_eq!(after, fresh);
    }
}
