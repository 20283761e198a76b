//! The dynamics of one joint state (all vectors `nv` long, model order, joint space):
//!
//! ```text
//! g  = RNEA(q, 0, 0)                gravity torques                      (~/gravity_effort)
//! q̈  = FD(q, q̇, τ_cmd)              forward dynamics under the command   (~/acceleration)
//! τ  = RNEA(q, q̇, q̈_measured)       efforts that explain the measured motion (~/measured_dynamics)
//! ```
//!
//! All three come from one [`joint_state_outputs`] call (the joint transforms and the velocity
//! pass computed once). When it fails, the separate algorithms find out which outputs still
//! hold: the node's pair (`g`, `q̈`) stands or falls together, `τ` on its own.

use spatial_dynamics_core::algorithms::{
    forward_dynamics, gravity, joint_state_outputs, rnea, JointStateInputs, JointStateOutputs,
};
use spatial_dynamics_core::{Externals, ForwardDynamicsMethod, Model, Workspace};

/// What [`JointStateDynamics::evaluate`] could compute.
#[derive(Debug)]
pub struct Evaluated {
    /// `g` and `q̈ = FD(…)`, or why not.
    pub node: Result<(), String>,
    /// `τ = RNEA(q, q̇, q̈_measured)`, or why not (`Ok` when no measured acceleration was given).
    pub measured: Result<(), String>,
}

/// Results and scratch for one joint state at a time (sized once for a model; nothing is
/// allocated per state).
#[derive(Clone, Debug)]
pub struct JointStateDynamics {
    combined: JointStateOutputs,
    /// Whether the last results are in `combined` (else in the one-by-one buffers).
    from_combined: bool,
    g: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
}

impl JointStateDynamics {
    pub fn new(model: &Model) -> Self {
        JointStateDynamics {
            combined: JointStateOutputs::new(model),
            from_combined: true,
            g: vec![0.0; model.nv()],
            qdd: vec![0.0; model.nv()],
            tau: vec![0.0; model.nv()],
        }
    }

    /// Gravity, forward dynamics by `method` and (with a measured acceleration) inverse
    /// dynamics at `input`. Base at rest in an inertial frame, no external wrenches.
    pub fn evaluate(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        method: ForwardDynamicsMethod,
        input: &JointStateInputs<'_>,
    ) -> Evaluated {
        self.from_combined =
            joint_state_outputs(model, ws, method, input, &mut self.combined).is_ok();
        if self.from_combined {
            return Evaluated {
                node: Ok(()),
                measured: Ok(()),
            };
        }
        let JointStateInputs { q, v, .. } = *input;
        let node = gravity(model, ws, q)
            .map(|g| self.g.copy_from_slice(g))
            .and_then(|_| {
                let (tau, none) = (input.effort_command, Externals::none());
                forward_dynamics(model, ws, q, v, tau, method, &none)
            })
            .map(|qdd| self.qdd.copy_from_slice(qdd));
        let measured = match input.measured_acceleration {
            Some(a) => rnea(model, ws, q, v, a).map(|tau| self.tau.copy_from_slice(tau)),
            None => Ok(()),
        };
        Evaluated {
            node: node.map_err(|e| e.to_string()),
            measured: measured.map_err(|e| e.to_string()),
        }
    }

    /// `g(q)` of the last [`evaluate`](Self::evaluate) (when its `node` is `Ok`).
    pub fn gravity(&self) -> &[f64] {
        match self.from_combined {
            true => self.combined.gravity(),
            false => &self.g,
        }
    }

    /// `q̈ = FD(q, q̇, τ_cmd)` of the last [`evaluate`](Self::evaluate) (when its `node` is `Ok`).
    pub fn acceleration(&self) -> &[f64] {
        match self.from_combined {
            true => self.combined.acceleration(),
            false => &self.qdd,
        }
    }

    /// `τ = RNEA(q, q̇, q̈_measured)` of the last [`evaluate`](Self::evaluate) (when it had a
    /// measured acceleration and its `measured` is `Ok`).
    pub fn inverse_dynamics(&self) -> &[f64] {
        match self.from_combined {
            true => self.combined.inverse_dynamics(),
            false => &self.tau,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
    use spatial_dynamics_core::{urdf, ModelOptions};

    /// A state the combined call refuses (an overflowing velocity) still reports which of the
    /// outputs hold, by the separate algorithms.
    #[test]
    fn outputs_agree_with_the_separate_algorithms_and_failures_are_told_apart() {
        let model = urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap();
        let mut ws = Workspace::new(&model);
        let mut d = JointStateDynamics::new(&model);
        let q: Vec<f64> = (0..model.nq()).map(|k| 0.1 * k as f64).collect();
        let v: Vec<f64> = (0..model.nv()).map(|k| 0.3 - 0.05 * k as f64).collect();
        let tau: Vec<f64> = (0..model.nv()).map(|k| 1.0 - 0.2 * k as f64).collect();
        let a: Vec<f64> = (0..model.nv()).map(|k| -0.5 + 0.1 * k as f64).collect();
        let input = JointStateInputs {
            q: &q,
            v: &v,
            effort_command: &tau,
            measured_acceleration: Some(&a),
        };
        let e = d.evaluate(&model, &mut ws, ForwardDynamicsMethod::Aba, &input);
        assert!(e.node.is_ok() && e.measured.is_ok());
        let (g, qdd, id) = (
            d.gravity().to_vec(),
            d.acceleration().to_vec(),
            d.inverse_dynamics().to_vec(),
        );
        let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(a, b)| (a - b).abs() < 1e-9);
        assert!(close(&g, gravity(&model, &mut ws, &q).unwrap()));
        let none = Externals::none();
        let fd = forward_dynamics(
            &model,
            &mut ws,
            &q,
            &v,
            &tau,
            ForwardDynamicsMethod::Aba,
            &none,
        );
        assert!(close(&qdd, fd.unwrap()));
        assert!(close(&id, rnea(&model, &mut ws, &q, &v, &a).unwrap()));

        // Huge velocities overflow: gravity alone would hold, but FD and RNEA fail.
        let fast = vec![1e200; model.nv()];
        let input = JointStateInputs { v: &fast, ..input };
        let e = d.evaluate(&model, &mut ws, ForwardDynamicsMethod::Aba, &input);
        assert!(e.node.is_err() && e.measured.is_err(), "{e:?}");
    }
}
