//! Input and output checks shared by the algorithms: lengths, finiteness, unit quaternions.
//! Each error names the coordinate (joint) and the value.

use super::Externals;
use crate::error::{check_len, DynamicsError};
use crate::model::{quaternion_is_usable, quaternion_norm, JointKind, Model};
use crate::Workspace;

/// `ws` was made for `model` ([`Workspace::check`]), `q` has `nq` finite values and every
/// floating joint's quaternion is not (near) zero.
pub(crate) fn check_q(model: &Model, ws: &Workspace, q: &[f64]) -> Result<(), DynamicsError> {
    ws.check(model)?;
    check_len("q", model.nq, q.len())?;
    if !all_finite(q) {
        let index = q.iter().position(|x| !x.is_finite()).unwrap_or(0);
        return Err(non_finite_q(model, q, index));
    }
    check_quaternions(model, q)
}

/// Every floating joint's quaternion in `q` (of `nq` finite values) is not (near) zero.
#[inline]
fn check_quaternions(model: &Model, q: &[f64]) -> Result<(), DynamicsError> {
    if model.nq == model.nv {
        // No floating joint: it is the only one with more position than velocity coordinates.
        return Ok(());
    }
    for body in &model.bodies {
        let joint = &body.joint;
        if joint.kind == JointKind::Floating && !joint.is_mimic() {
            let q_index = joint.coords.q_index;
            check_quaternion(&joint.name, &q[q_index + 3..q_index + 7])?;
        }
    }
    Ok(())
}

/// `q` has `nq` values, and the coordinates the joints of `bodies` read are finite and their
/// floating joints' quaternions not (near) zero: what an algorithm that places only these
/// bodies (a frame's support) needs, the same errors as [`check_q`] for the coordinates it
/// reads. The other coordinates are not looked at.
pub(crate) fn check_q_of(model: &Model, q: &[f64], bodies: &[usize]) -> Result<(), DynamicsError> {
    check_len("q", model.nq, q.len())?;
    // `x · 0` is zero for a finite `x`, NaN otherwise: one test for all the coordinates; the
    // quaternions are checked once they are known to be finite (as `check_q` orders them).
    let mut sum = 0.0;
    for &i in bodies {
        let joint = &model.bodies[i].joint;
        for x in &q[joint.coords.q_index..joint.coords.q_index + joint.kind.nq()] {
            sum += x * 0.0;
        }
    }
    if sum != 0.0 {
        let index = bodies
            .iter()
            .flat_map(|&i| {
                let joint = &model.bodies[i].joint;
                joint.coords.q_index..joint.coords.q_index + joint.kind.nq()
            })
            .find(|&k| !q[k].is_finite())
            .unwrap_or(0);
        return Err(non_finite_q(model, q, index));
    }
    for &i in bodies {
        let joint = &model.bodies[i].joint;
        if joint.kind == JointKind::Floating {
            let q_index = joint.coords.q_index;
            check_quaternion(&joint.name, &q[q_index + 3..q_index + 7])?;
        }
    }
    Ok(())
}

/// The error for the non-finite `q[index]`, naming its joint.
#[cold]
fn non_finite_q(model: &Model, q: &[f64], index: usize) -> DynamicsError {
    let coordinate = match model.joint_of_q(index) {
        Some((name, 0)) => name.to_string(),
        Some((name, k)) => format!("{name}[{k}]"),
        None => format!("q[{index}]"),
    };
    DynamicsError::NonFinite {
        vector: "q",
        index,
        coordinate,
        value: q[index],
    }
}

/// A floating joint's quaternion `[x, y, z, w]` must be neither (near) zero, `|quat| ≥ 10⁻⁹`,
/// nor so large its squared norm overflows ([`quaternion_is_usable`]); the norm is only taken
/// for the error. A NaN passes here and is caught as a non-finite coordinate.
#[inline(always)]
fn check_quaternion(joint: &str, quat: &[f64]) -> Result<(), DynamicsError> {
    if !quaternion_is_usable(quat) {
        return Err(DynamicsError::BadQuaternion {
            joint: joint.to_string(),
            norm: quaternion_norm(quat),
        });
    }
    Ok(())
}

/// A velocity-like vector (`v`, `a`, `τ`) has `nv` finite values.
pub(crate) fn check_v(model: &Model, vector: &'static str, x: &[f64]) -> Result<(), DynamicsError> {
    check_len(vector, model.nv, x.len())?;
    if all_finite(x) {
        return Ok(());
    }
    match x.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(DynamicsError::NonFinite {
            vector,
            index,
            coordinate: model.v_name(index),
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// The external wrenches, if any, are one finite wrench per body.
pub(crate) fn check_externals(model: &Model, ext: &Externals<'_>) -> Result<(), DynamicsError> {
    if let Some(w) = ext.wrenches {
        check_len("external wrenches", model.nbodies(), w.len())?;
        if let Some(i) = w.iter().position(|f| !f.is_finite()) {
            return Err(DynamicsError::NonFiniteWrench {
                body: model.bodies[i].name.clone(),
            });
        }
    }
    if !(ext.root_velocity.is_finite() && ext.root_acceleration.is_finite()) {
        return Err(DynamicsError::NonFiniteWrench {
            body: "root motion".into(),
        });
    }
    Ok(())
}

/// The inputs of inverse dynamics: the workspace, `q`, `v`, `a` and the externals.
pub(crate) fn check_inverse_inputs(
    model: &Model,
    ws: &Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
    ext: &Externals<'_>,
) -> Result<(), DynamicsError> {
    // The common case in one pass: every length right and every value finite. Otherwise the
    // checks one by one, which name the first bad vector and value.
    let lengths = q.len() == model.nq && v.len() == model.nv && a.len() == model.nv;
    if lengths && all_finite(q) & all_finite(v) & all_finite(a) {
        ws.check(model)?;
        check_quaternions(model, q)?;
        return check_externals(model, ext);
    }
    check_q(model, ws, q)?;
    check_v(model, "v", v)?;
    check_v(model, "a", a)?;
    check_externals(model, ext)
}

/// The inputs of forward dynamics: the workspace, `q`, `v`, `τ` and the externals.
pub(crate) fn check_forward_inputs(
    model: &Model,
    ws: &Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<(), DynamicsError> {
    check_q(model, ws, q)?;
    check_v(model, "v", v)?;
    check_v(model, "tau", tau)?;
    check_externals(model, ext)
}

/// A result vector is finite; names the first coordinate that is not.
pub(crate) fn check_result(
    model: &Model,
    quantity: &'static str,
    x: &[f64],
) -> Result<(), DynamicsError> {
    if all_finite(x) {
        return Ok(());
    }
    match x.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(DynamicsError::NonFiniteResult {
            quantity,
            coordinate: model.v_name(index),
        }),
        None => Ok(()),
    }
}

/// True when every value is finite, without a branch per value: `x · 0` is zero for a finite
/// `x` and NaN otherwise, summed in four independent lanes (which vectorise).
#[inline]
pub(crate) fn all_finite(values: &[f64]) -> bool {
    finite_in_lanes::<4>(values)
}

/// [`all_finite`] for a matrix's storage (thousands of values), summed in sixteen lanes: four
/// independent vector additions per step, where four lanes make one register whose every
/// addition waits on the one before.
#[inline]
pub(crate) fn all_finite_long(values: &[f64]) -> bool {
    finite_in_lanes::<16>(values)
}

/// `Σ x · 0` over `values` in `L` lanes (a power of two), joined in adjacent pairs
/// (`(l₀ + l₁) + (l₂ + l₃)` for four), is zero.
#[inline(always)]
fn finite_in_lanes<const L: usize>(values: &[f64]) -> bool {
    let mut lanes = [0.0f64; L];
    let chunks = values.chunks_exact(L);
    for (k, x) in chunks.remainder().iter().enumerate() {
        lanes[k] += x * 0.0;
    }
    for chunk in chunks {
        for k in 0..L {
            lanes[k] += chunk[k] * 0.0;
        }
    }
    let mut width = L;
    while width > 1 {
        width /= 2;
        for k in 0..width {
            lanes[k] = lanes[2 * k] + lanes[2 * k + 1];
        }
    }
    lanes[0] == 0.0
}

#[cfg(test)]
mod tests {
    use super::{all_finite, all_finite_long};

    /// Both probes find one NaN or infinity wherever it sits, in the lanes and in the remainder,
    /// for every length up to three full rounds of sixteen, and pass finite values of any size
    /// and sign (`−0` included).
    #[test]
    fn the_probes_find_a_non_finite_value_at_every_position() {
        for n in 0..50 {
            let finite: Vec<f64> = (0..n)
                .map(|i| match i % 3 {
                    0 => -0.0,
                    1 => 1e300 * (i as f64),
                    _ => -1e-300,
                })
                .collect();
            assert!(all_finite(&finite) && all_finite_long(&finite), "{n}");
            for at in 0..n {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut x = finite.clone();
                    x[at] = bad;
                    assert!(!all_finite(&x), "{n} {at} {bad}");
                    assert!(!all_finite_long(&x), "{n} {at} {bad}");
                }
            }
        }
    }
}
