//! The Jacobians of `q' = q ⊕ v·dt` ([`Model::integrate`]) on the tangent of
//! [the module](super): `q ⊕ δq` perturbs `q`, `q' ⊕ δq'` measures the result, so that
//!
//! ```text
//! (q ⊕ δq) ⊕ (v + δv)·dt = q' ⊕ (D_q δq + D_v δv·dt)   to first order,
//! ```
//!
//! Pinocchio's `dIntegrate` (`D_q` its `ARG0`, `D_v` its `ARG1`, with `dt` folded into `v`).
//! Every joint that adds `v·dt` to its coordinates (revolute, continuous, prismatic, planar)
//! has identity blocks. A floating joint moves by the SE(3) exponential of its body twist,
//! `M' = M exp(u)` with `u = v·dt = [ρ; φ]` (linear, then angular), so
//!
//! ```text
//! M exp(δq) exp(u + δu) = M' exp(Ad_{exp(u)}⁻¹ δq + J_r(u) δu):
//! D_q = Ad_{exp(u)}⁻¹ = [Rᵀ  −Rᵀ p×; 0  Rᵀ]   with exp(u) = (R, p),
//! D_v = J_r(u)        = [J_r3(φ)  Q_r(ρ, φ); 0  J_r3(φ)],
//! ```
//!
//! `J_r3(φ) = 1 − (1 − cos θ)/θ² φ× + (θ − sin θ)/θ³ φ×²` (θ = |φ|) the right Jacobian of
//! SO(3), and `Q_r(ρ, φ) = Q(−ρ, −φ)` with Barfoot's `Q` (State Estimation for Robotics,
//! eq. 7.86; the left Jacobian of SE(3) is `[J Q; 0 J]` and `J_r(u) = J_l(−u)`):
//!
//! ```text
//! Q(ρ, φ) = ½ ρ× + c₁ (φ×ρ× + ρ×φ× + φ×ρ×φ×) + c₂ (φ×φ×ρ× + ρ×φ×φ× − 3 φ×ρ×φ×)
//!           + c₃ (φ×ρ×φ×φ× + φ×φ×ρ×φ×),
//! c₁ = (θ − sin θ)/θ³,  c₂ = (θ² + 2 cos θ − 2)/(2θ⁴),  c₃ = (2θ − 3 sin θ + θ cos θ)/(2θ⁵).
//! ```
//!
//! `exp(u)` itself is the floating joint's own integration of `u` from the identity, the map
//! the simulator steps with; below θ = 0.05 the coefficients come from their Taylor series to
//! θ⁴ (error below 1e-16 relative), where the closed forms lose digits to cancellation.

use crate::algorithms::validate::check_v;
use crate::error::{check_len, DynamicsError};
use crate::model::{JointKind, Model};
use crate::spatial::{skew, Matrix3, Matrix6, Vector3};
use nalgebra::{DMatrix, Quaternion, UnitQuaternion};

/// Below this rotation angle (rad) the Jacobians' coefficients come from their series.
const SERIES_BELOW: f64 = 0.05;

/// Above this rotation angle (rad) `θ⁵` may overflow: the coefficients are divided by `θ`
/// term by term.
const POWERS_OVERFLOW_ABOVE: f64 = 1e60;

/// `D_q` and `D_v` of `q ⊕ v·dt` for the whole model into `dq` and `dv` (each `nv × nv`,
/// block diagonal: identity blocks but for floating joints, whose 6 × 6 blocks the module
/// doc gives; zero elsewhere). `q` must have `nq` values, `v` `nv` finite ones, the matrices
/// `nv × nv` (else [`DynamicsError::Length`] or [`DynamicsError::NonFinite`] names the
/// argument), `dt` must be finite ([`DynamicsError::BadStep`]); a floating joint's step `v·dt`
/// whose angle overflows is [`DynamicsError::NonFiniteResult`], naming the joint.
pub fn integrate_jacobians(
    model: &Model,
    q: &[f64],
    v: &[f64],
    dt: f64,
    dq: &mut DMatrix<f64>,
    dv: &mut DMatrix<f64>,
) -> Result<(), DynamicsError> {
    let nv = model.nv();
    check_len("q", model.nq(), q.len())?;
    check_v(model, "v", v)?;
    if !dt.is_finite() {
        return Err(DynamicsError::BadStep { dt });
    }
    check_len("dq (rows)", nv, dq.nrows())?;
    check_len("dq (columns)", nv, dq.ncols())?;
    check_len("dv (rows)", nv, dv.nrows())?;
    check_len("dv (columns)", nv, dv.ncols())?;
    dq.fill_with_identity();
    dv.fill_with_identity();
    for j in model.coordinate_joints() {
        if let JointKind::Floating = j.kind {
            let s = j.v_index;
            let u: [f64; 6] = std::array::from_fn(|k| v[s + k] * dt);
            let turn = Vector3::new(u[3], u[4], u[5]).norm();
            if !(u.iter().all(|x| x.is_finite()) && turn.is_finite()) {
                return Err(DynamicsError::NonFiniteResult {
                    quantity: "the step v·dt",
                    coordinate: j.name.to_string(),
                });
            }
            let (block_q, block_v) = floating_jacobians(&u);
            if !block_q.iter().chain(block_v.iter()).all(|x| x.is_finite()) {
                return Err(DynamicsError::NonFiniteResult {
                    quantity: "the Jacobians of the step v·dt",
                    coordinate: j.name.to_string(),
                });
            }
            dq.fixed_view_mut::<6, 6>(s, s).copy_from(&block_q);
            dv.fixed_view_mut::<6, 6>(s, s).copy_from(&block_v);
        }
    }
    Ok(())
}

/// `(Ad_{exp(u)}⁻¹, J_r(u))` of a floating joint's step `u = [ρ; φ]` (module doc).
pub(crate) fn floating_jacobians(u: &[f64; 6]) -> (Matrix6, Matrix6) {
    // exp(u) = (R, p) exactly as the joint integrates it: from the identity pose, by u.
    let mut pose = [0.0; 7];
    JointKind::Floating.integrate(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], u, 1.0, &mut pose);
    let rotation =
        UnitQuaternion::from_quaternion(Quaternion::new(pose[6], pose[3], pose[4], pose[5]))
            .to_rotation_matrix()
            .into_inner();
    let p = Vector3::new(pose[0], pose[1], pose[2]);
    let rt = rotation.transpose();
    let mut ad_inv = Matrix6::zeros();
    ad_inv.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
    ad_inv
        .fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-rt * skew(&p)));
    ad_inv.fixed_view_mut::<3, 3>(3, 3).copy_from(&rt);

    let (rho, phi) = (
        Vector3::new(u[0], u[1], u[2]),
        Vector3::new(u[3], u[4], u[5]),
    );
    let (r, w) = (skew(&rho), skew(&phi));
    let theta = phi.norm();
    let [j1, c1, c2, c3] = coefficients(theta);
    let jr3 = Matrix3::identity() - w * j1 + w * w * c1;
    // Q(−ρ, −φ): the terms odd in (ρ, φ) change sign.
    let wrw = w * r * w;
    let q_r = -r * 0.5 + (w * r + r * w - wrw) * c1 - (w * w * r + r * w * w - wrw * 3.0) * c2
        + (wrw * w + w * wrw) * c3;
    let mut jr = Matrix6::zeros();
    jr.fixed_view_mut::<3, 3>(0, 0).copy_from(&jr3);
    jr.fixed_view_mut::<3, 3>(0, 3).copy_from(&q_r);
    jr.fixed_view_mut::<3, 3>(3, 3).copy_from(&jr3);
    (ad_inv, jr)
}

/// `[(1 − cos θ)/θ², c₁, c₂, c₃]` of the module doc, by series below [`SERIES_BELOW`]; beyond
/// [`POWERS_OVERFLOW_ABOVE`] divided term by term, so that no power of θ overflows for any
/// finite θ (each coefficient tends to 0).
fn coefficients(theta: f64) -> [f64; 4] {
    let t2 = theta * theta;
    if theta < SERIES_BELOW {
        [
            0.5 - t2 / 24.0 + t2 * t2 / 720.0,
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0,
            1.0 / 24.0 - t2 / 720.0 + t2 * t2 / 40320.0,
            1.0 / 120.0 - t2 / 2520.0 + t2 * t2 / 120960.0,
        ]
    } else {
        let (s, c) = theta.sin_cos();
        if theta < POWERS_OVERFLOW_ABOVE {
            [
                (1.0 - c) / t2,
                (theta - s) / (t2 * theta),
                (t2 + 2.0 * c - 2.0) / (2.0 * t2 * t2),
                (2.0 * theta - 3.0 * s + theta * c) / (2.0 * t2 * t2 * theta),
            ]
        } else {
            [
                (1.0 - c) / t2,
                (1.0 - s / theta) / t2,
                (1.0 + (2.0 * c - 2.0) / t2) / (2.0 * t2),
                (2.0 + c - 3.0 * s / theta) / (2.0 * t2) / t2,
            ]
        }
    }
}
