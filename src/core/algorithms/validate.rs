//! Input and output checks shared by the algorithms: lengths, finiteness, unit quaternions.
//! Each error names the coordinate (joint) and the value.

use super::Externals;
use crate::error::DynamicsError;
use crate::model::{JointKind, Model};

/// `q` has `nq` finite values and every floating joint's quaternion is not (near) zero.
pub(crate) fn check_q(model: &Model, q: &[f64]) -> Result<(), DynamicsError> {
    check_len("q", model.nq, q.len())?;
    if let Some(index) = q.iter().position(|x| !x.is_finite()) {
        let coordinate = match model.joint_of_q(index) {
            Some((name, 0)) => name.to_string(),
            Some((name, k)) => format!("{name}[{k}]"),
            None => format!("q[{index}]"),
        };
        return Err(DynamicsError::NonFinite {
            vector: "q",
            index,
            coordinate,
            value: q[index],
        });
    }
    for joint in model.coordinate_joints() {
        if *joint.kind == JointKind::Floating {
            let quat = &q[joint.q_index + 3..joint.q_index + 7];
            let norm = quat.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm < 1e-9 {
                return Err(DynamicsError::BadQuaternion {
                    joint: joint.name.to_string(),
                    norm,
                });
            }
        }
    }
    Ok(())
}

/// A velocity-like vector (`v`, `a`, `τ`) has `nv` finite values.
pub(crate) fn check_v(model: &Model, vector: &'static str, x: &[f64]) -> Result<(), DynamicsError> {
    check_len(vector, model.nv, x.len())?;
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

/// The inputs of forward dynamics: `q`, `v`, `τ` and the externals.
pub(crate) fn check_forward_inputs(
    model: &Model,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<(), DynamicsError> {
    check_q(model, q)?;
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
    match x.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(DynamicsError::NonFiniteResult {
            quantity,
            coordinate: model.v_name(index),
        }),
        None => Ok(()),
    }
}

fn check_len(vector: &'static str, expected: usize, got: usize) -> Result<(), DynamicsError> {
    if expected == got {
        Ok(())
    } else {
        Err(DynamicsError::Length {
            vector,
            expected,
            got,
        })
    }
}
