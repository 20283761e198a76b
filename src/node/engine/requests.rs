//! What the services' requests and responses share: the state a request gives (joint arrays
//! by name, the floating base explicitly) and the answer of a refused request.

use super::Engine;
use crate::ros::msgs::*;

/// A request that gives the state as joint arrays by name (`name`, `position`, `velocity`)
/// and the floating base's pose (`base_pose`, in the world) and twist (`base_twist`, in the base
/// frame).
pub(super) trait StateRequest {
    /// `(name, position, velocity, base_pose, base_twist)`.
    fn state(&self) -> (&[String], &[f64], &[f64], &Pose, &Twist);
}

macro_rules! state_request {
    ($($request:ty),*) => {$(
        impl StateRequest for $request {
            fn state(&self) -> (&[String], &[f64], &[f64], &Pose, &Twist) {
                let r = self;
                (&r.name, &r.position, &r.velocity, &r.base_pose, &r.base_twist)
            }
        }
    )*};
}

state_request!(
    InverseDynamicsRequest,
    ForwardDynamicsRequest,
    FrameKinematicsRequest,
    LinearizeRequest,
    ResetRequest
);

/// A response that answers a refused request: `success` false, the reason in `message`, every
/// other field empty.
pub(crate) trait Refused: Default {
    fn refused(message: String) -> Self;
}

macro_rules! refused {
    ($($response:ty),*) => {$(
        impl Refused for $response {
            fn refused(message: String) -> Self {
                Self {
                    message,
                    ..Default::default()
                }
            }
        }
    )*};
}

refused!(
    InverseDynamicsResponse,
    ForwardDynamicsResponse,
    MassMatrixResponse,
    FrameKinematicsResponse,
    LinearizeResponse,
    ResetResponse
);

/// Why a computed answer is refused when one of its numbers is not finite.
pub(super) const NOT_FINITE: &str =
    "the result was not finite: the state is too extreme to compute with";

impl Engine {
    /// Fills `q` and `v` from a request's state ([`Engine::read_state`] with its base fields).
    pub(super) fn read_request_state(&mut self, req: &impl StateRequest) -> Result<(), String> {
        let (names, position, velocity, base_pose, base_twist) = req.state();
        self.read_state(names, position, velocity, Some(base_pose), Some(base_twist))
    }
}
