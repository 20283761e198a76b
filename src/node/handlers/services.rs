//! The node's services: each handler takes the decoded request and returns the response
//! (`success = false` with the reason for a request the engine refuses, or whose result is not
//! finite).

use super::finite::Finite;
use super::{NodeState, Outputs};
use crate::node::engine::requests::Refused;
use crate::ros::msgs::*;
use std::time::Instant;

/// `response`, or a refusal when a number in it is not finite.
fn finite_or_refused<R: Finite + Refused>(response: R) -> R {
    match response.non_finite() {
        None => response,
        Some(field) => R::refused(format!("the result was not finite ({field})")),
    }
}

impl NodeState {
    /// `~/inverse_dynamics`: τ = RNEA(q, q̇, q̈, external wrenches).
    pub fn inverse_dynamics(
        &mut self,
        request: &InverseDynamicsRequest,
    ) -> InverseDynamicsResponse {
        finite_or_refused(self.engine.inverse_dynamics(request))
    }

    /// `~/forward_dynamics`: q̈ = FD(q, q̇, τ, external wrenches).
    pub fn forward_dynamics(
        &mut self,
        request: &ForwardDynamicsRequest,
    ) -> ForwardDynamicsResponse {
        finite_or_refused(self.engine.forward_dynamics(request))
    }

    /// `~/mass_matrix`: H(q), row-major.
    pub fn mass_matrix(&mut self, request: &MassMatrixRequest) -> MassMatrixResponse {
        finite_or_refused(self.engine.mass_matrix(request))
    }

    /// `~/frame_kinematics`.
    pub fn frame_kinematics(
        &mut self,
        request: &FrameKinematicsRequest,
    ) -> FrameKinematicsResponse {
        self.engine.frame_kinematics(request)
    }

    /// `~/linearize`: `A`, `B` of `x = [q; v]`, `u = τ`, continuous or over one step.
    pub fn linearize(&mut self, request: &LinearizeRequest) -> LinearizeResponse {
        self.engine.linearize(request)
    }

    /// `~/describe_model`.
    pub fn describe_model(&self) -> DescribeModelResponse {
        self.engine.describe()
    }

    /// `~/reset` (simulate mode): the simulated state back to its start, or to the request's.
    pub fn reset(&mut self, request: &ResetRequest) -> ResetResponse {
        self.engine.simulation_reset(request)
    }

    /// `~/pause` (simulate mode): `data` true pauses the simulation, false resumes it.
    pub fn pause(&mut self, request: &SetBoolRequest) -> SetBoolResponse {
        match self.engine.simulation_pause(request.data) {
            Ok(message) => SetBoolResponse {
                success: true,
                message,
            },
            Err(message) => SetBoolResponse {
                success: false,
                message,
            },
        }
    }

    /// `~/step` (simulate mode, paused): one `sim_dt` step at wall time `at`; the answer gives
    /// the simulated time reached, and the outputs are the step's, as a tick's.
    pub fn step(&mut self, at: Instant) -> (TriggerResponse, Outputs) {
        match self.engine.simulation_step(at) {
            Ok((js, stamp)) => {
                let response = TriggerResponse {
                    success: true,
                    message: format!("t = {}.{:09} s", stamp.sec, stamp.nanosec),
                };
                (response, self.simulation_outputs(Some(Ok((js, stamp)))))
            }
            Err(message) => (
                TriggerResponse {
                    success: false,
                    message,
                },
                Outputs::default(),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use crate::node::params::Settings;
    use spatial_dynamics_core::model::examples::PARTICLE_URDF;

    const THETA: f64 = 1.1;

    fn joint1() -> Vec<String> {
        vec!["joint1".into()]
    }

    #[test]
    fn dynamics_services_answer_the_pendulums_closed_forms() {
        let mut state = serving(pendulum());
        let (rate, accel) = (0.5, -2.0);
        let id = state.inverse_dynamics(&InverseDynamicsRequest {
            name: joint1(),
            position: vec![THETA],
            velocity: vec![rate],
            acceleration: vec![accel],
            ..Default::default()
        });
        assert!(id.success, "{}", id.message);
        assert_close(
            id.effort[0],
            pendulum_inertia() * accel + pendulum_gravity(THETA),
        );
        let effort = 3.0;
        let fd = state.forward_dynamics(&ForwardDynamicsRequest {
            name: joint1(),
            position: vec![THETA],
            velocity: vec![rate],
            effort: vec![effort],
            ..Default::default()
        });
        assert!(fd.success, "{}", fd.message);
        assert_close(
            fd.acceleration[0],
            (effort - pendulum_gravity(THETA)) / pendulum_inertia(),
        );
        let mm = state.mass_matrix(&MassMatrixRequest {
            name: joint1(),
            position: vec![THETA],
            ..Default::default()
        });
        assert!(mm.success, "{}", mm.message);
        assert_eq!(mm.matrix.len(), 1);
        assert_close(mm.matrix[0], pendulum_inertia());
        // The rod's centre of mass, at L/2 along its axis, −z turned by θ about y.
        let fk = state.frame_kinematics(&FrameKinematicsRequest {
            name: joint1(),
            position: vec![THETA],
            links: vec!["link1".into()],
            ..Default::default()
        });
        assert!(fk.success, "{}", fk.message);
        assert_close(fk.mass, MASS);
        let c = &fk.center_of_mass;
        assert_close(c.x, -LENGTH / 2.0 * THETA.sin());
        assert_close(c.y, 0.0);
        assert_close(c.z, -LENGTH / 2.0 * THETA.cos());
        let described = state.describe_model();
        assert_eq!((described.nq, described.nv), (1, 1));
        assert_eq!(described.joint_names, joint1());
    }

    #[test]
    fn bad_requests_are_answered_unsuccessfully_with_the_reason_and_no_numbers() {
        let mut state = serving(pendulum());
        let id = state.inverse_dynamics(&InverseDynamicsRequest {
            name: vec!["elbow".into()],
            position: vec![THETA],
            ..Default::default()
        });
        assert!(!id.success && id.effort.is_empty());
        assert!(
            id.message.contains("unknown joint 'elbow'"),
            "{}",
            id.message
        );
        // Finite inputs whose dynamics overflow: an effort of 1e308 N·m on an inertia of
        // m l² / 3 ≈ 0.53 kg·m² is an acceleration of ≈ 1.9e308 rad/s², beyond f64.
        let fd = state.forward_dynamics(&ForwardDynamicsRequest {
            name: joint1(),
            position: vec![THETA],
            velocity: vec![0.0],
            effort: vec![1e308],
            ..Default::default()
        });
        assert!(!fd.success && fd.acceleration.is_empty() && !fd.message.is_empty());
        let mm = state.mass_matrix(&MassMatrixRequest {
            name: joint1(),
            position: vec![f64::NAN],
            ..Default::default()
        });
        assert!(!mm.success && mm.matrix.is_empty() && !mm.message.is_empty());
    }

    #[test]
    fn a_result_that_is_not_finite_becomes_a_refusal() {
        let good = MassMatrixResponse {
            success: true,
            matrix: vec![1.0],
            ..Default::default()
        };
        assert_eq!(finite_or_refused(good.clone()), good);
        let bad = MassMatrixResponse {
            matrix: vec![f64::INFINITY],
            ..good
        };
        let answer = finite_or_refused(bad);
        assert!(!answer.success && answer.matrix.is_empty());
        assert_eq!(answer.message, "the result was not finite (matrix[0])");
    }

    #[test]
    fn pause_step_and_reset_drive_the_simulation() {
        let mut serve = serving(pendulum());
        let pause = serve.pause(&SetBoolRequest { data: true });
        assert!(!pause.success && pause.message.contains("not in simulate mode"));
        assert!(!serve.step(Instant::now()).0.success);

        // The particle, 1 kg under gravity; one semi-implicit Euler step of dt:
        // v = −g dt, then z = v dt.
        let dt = 1e-3;
        let mut sim = serving(Settings {
            robot_description: PARTICLE_URDF.into(),
            simulate: true,
            sim_dt: dt,
            ..Settings::default()
        });
        let (running, out) = sim.step(Instant::now());
        assert!(!running.success && running.message.contains("pause it first"));
        assert!(out.joint_states.is_none());
        assert!(sim.pause(&SetBoolRequest { data: true }).success);
        let (stepped, out) = sim.step(Instant::now());
        assert!(stepped.success, "{}", stepped.message);
        assert_eq!(stepped.message, "t = 0.001000000 s");
        let js = out.joint_states.expect("the step's joint_states");
        assert_eq!(js.name, ["x", "z"]);
        assert_close(js.velocity[1], -G * dt);
        assert_close(js.position[1], -G * dt * dt);
        assert!(out.clock.is_none(), "publish_clock is off");
        let reset = sim.reset(&ResetRequest {
            name: vec!["z".into(), "x".into()],
            position: vec![2.0, 0.0],
            ..Default::default()
        });
        assert!(reset.success, "{}", reset.message);
        let js = sim.step(Instant::now()).1.joint_states.unwrap();
        assert_close(js.position[1], 2.0 - G * dt * dt);
        let bad = sim.reset(&ResetRequest {
            name: vec!["y".into()],
            position: vec![2.0],
            ..Default::default()
        });
        assert!(!bad.success && bad.message.contains("unknown joint 'y'"));
    }
}
