//! The node's services: each handler takes the decoded request and returns the response
//! (`success = false` with the reason for a request the engine refuses, or whose result is not
//! finite).

use super::finite::Finite;
use super::{NodeState, Outputs};
use crate::ros::msgs::*;
use std::time::Instant;

/// `response`, or the refusal `refused` builds when a number in it is not finite.
fn finite_or<R: Finite>(response: R, refused: impl FnOnce(String) -> R) -> R {
    if response.all_finite() {
        response
    } else {
        refused("the result was not finite".into())
    }
}

impl NodeState {
    /// `~/inverse_dynamics`: τ = RNEA(q, q̇, q̈, external wrenches).
    pub fn inverse_dynamics(
        &mut self,
        request: &InverseDynamicsRequest,
    ) -> InverseDynamicsResponse {
        finite_or(self.engine.inverse_dynamics(request), |message| {
            InverseDynamicsResponse {
                message,
                ..Default::default()
            }
        })
    }

    /// `~/forward_dynamics`: q̈ = FD(q, q̇, τ, external wrenches).
    pub fn forward_dynamics(
        &mut self,
        request: &ForwardDynamicsRequest,
    ) -> ForwardDynamicsResponse {
        finite_or(self.engine.forward_dynamics(request), |message| {
            ForwardDynamicsResponse {
                message,
                ..Default::default()
            }
        })
    }

    /// `~/mass_matrix`: H(q), row-major.
    pub fn mass_matrix(&mut self, request: &MassMatrixRequest) -> MassMatrixResponse {
        finite_or(self.engine.mass_matrix(request), |message| {
            MassMatrixResponse {
                message,
                ..Default::default()
            }
        })
    }

    /// `~/frame_kinematics`.
    pub fn frame_kinematics(
        &mut self,
        request: &FrameKinematicsRequest,
    ) -> FrameKinematicsResponse {
        self.engine.frame_kinematics(request)
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
