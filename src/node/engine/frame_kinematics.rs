//! `~/frame_kinematics`: link poses, frame Jacobians and classical accelerations, and the centre
//! of mass with its Jacobian, at the state a request gives (see `msg/srv/FrameKinematics.srv`).
//!
//! The state is read as for `~/inverse_dynamics` (joint arrays by name, the floating base from
//! `base_pose`, `base_twist` and `base_accel`); every link is resolved before anything is
//! computed, so an unknown one fails the request with its name. The Jacobians come from one
//! pass over the tree ([`joint_jacobians`]) whatever the number of links; the accelerations from
//! one pass along each link's support.

use super::requests::{Refused, NOT_FINITE};
use super::Engine;
use crate::ros::msgs::{
    Accel, FrameKinematicsRequest, FrameKinematicsResponse, Point, Pose, Quaternion,
};
use nalgebra::{DMatrix, Rotation3, UnitQuaternion};
use spatial_dynamics_core::algorithms::{
    center_of_mass_jacobian, find_frame, frame_classical_acceleration, joint_jacobians, Frame,
    ReferenceFrame,
};
use spatial_dynamics_core::error::DynamicsError;
use spatial_dynamics_core::spatial::{Transform, Vector3};

impl Engine {
    /// `~/frame_kinematics`.
    pub fn frame_kinematics(&mut self, req: &FrameKinematicsRequest) -> FrameKinematicsResponse {
        self.frame_kinematics_of(req)
            .unwrap_or_else(FrameKinematicsResponse::refused)
    }

    fn frame_kinematics_of(
        &mut self,
        req: &FrameKinematicsRequest,
    ) -> Result<FrameKinematicsResponse, String> {
        self.read_request_state(req)?;
        self.read_acceleration(&req.acceleration, &req.base_accel)?;
        let reference = match req.reference.as_str() {
            "" => ReferenceFrame::LocalWorldAligned,
            name => name.parse().map_err(|e| format!("reference: {e}"))?,
        };
        // Each link answers 6 × nv numbers: a request may name each of the model's links once
        // (or one link that many times), not make the answer as large as it likes.
        if req.links.len() > self.model.links().len() {
            return Err(format!(
                "links has {} entries: at most {} (the model's number of links) per request",
                req.links.len(),
                self.model.links().len()
            ));
        }
        let frames = req
            .links
            .iter()
            .enumerate()
            .map(|(i, link)| find_frame(&self.model, link).map_err(|e| format!("links[{i}]: {e}")))
            .collect::<Result<Vec<Frame>, String>>()?;
        // The velocity coordinates in answer order: the base's six, then the joints as named.
        let (index, columns) = self.velocity_columns();

        // A model whose moving links have no mass (a massless pan-tilt head) still has frames:
        // its centre of mass is answered as mass 0 at the origin, Jacobian 0.
        let (mass, com_position, center_of_mass_jacobian) =
            match center_of_mass_jacobian(&self.model, &mut self.ws, &self.q) {
                Ok((com, jc)) => (com.mass, com.position, by_rows(jc, &index)),
                Err(DynamicsError::Unsupported {
                    method: "center of mass",
                    ..
                }) => (0.0, Vector3::zeros(), vec![0.0; 3 * index.len()]),
                Err(e) => return Err(e.to_string()),
            };
        // The classical acceleration belongs to the link origin: world axes unless local.
        let acceleration_axes = match reference {
            ReferenceFrame::Local => ReferenceFrame::Local,
            _ => ReferenceFrame::LocalWorldAligned,
        };
        let mut accelerations = Vec::with_capacity(frames.len());
        for (frame, link) in frames.iter().zip(&req.links) {
            let m = frame_classical_acceleration(
                &self.model,
                &mut self.ws,
                &self.q,
                &self.v,
                &self.a,
                frame,
                acceleration_axes,
            )
            .map_err(|e| format!("link '{link}': {e}"))?;
            accelerations.push(Accel {
                linear: m.lin.into(),
                angular: m.ang.into(),
            });
        }
        let mut all =
            joint_jacobians(&self.model, &mut self.ws, &self.q).map_err(|e| e.to_string())?;
        let (mut poses, mut jacobians) = (Vec::with_capacity(frames.len()), Vec::new());
        for (frame, link) in frames.iter().zip(&req.links) {
            let placement = all
                .placement(frame)
                .map_err(|e| format!("link '{link}': {e}"))?;
            poses.push(pose(&placement));
            let j = all
                .frame_jacobian(frame, reference)
                .map_err(|e| format!("link '{link}': {e}"))?;
            jacobians.extend(by_rows(j, &index));
        }
        let numbers = [mass]
            .into_iter()
            .chain(com_position.iter().copied())
            .chain(poses.iter().flat_map(|p: &Pose| {
                let (x, o) = (&p.position, &p.orientation);
                [x.x, x.y, x.z, o.x, o.y, o.z, o.w]
            }))
            .chain(accelerations.iter().flat_map(|a: &Accel| {
                [
                    a.linear.x,
                    a.linear.y,
                    a.linear.z,
                    a.angular.x,
                    a.angular.y,
                    a.angular.z,
                ]
            }));
        if !numbers
            .chain(jacobians.iter().copied())
            .chain(center_of_mass_jacobian.iter().copied())
            .all(f64::is_finite)
        {
            return Err(NOT_FINITE.into());
        }
        Ok(FrameKinematicsResponse {
            success: true,
            message: String::new(),
            links: req.links.clone(),
            poses,
            columns,
            jacobians,
            accelerations,
            mass,
            center_of_mass: Point {
                x: com_position.x,
                y: com_position.y,
                z: com_position.z,
            },
            center_of_mass_jacobian,
        })
    }
}

/// The rows of `m`, each with its columns `index` in that order, concatenated (row-major).
fn by_rows(m: &DMatrix<f64>, index: &[usize]) -> Vec<f64> {
    m.row_iter()
        .flat_map(|row| index.iter().map(move |&c| row[c]))
        .collect()
}

/// The pose of a link frame in the world from its placement `ᴸX_0` (origin `trans`, axes
/// `rotᵀ`).
fn pose(x: &Transform) -> Pose {
    let rotation = Rotation3::from_matrix_unchecked(x.rot.transpose());
    let q = UnitQuaternion::from_rotation_matrix(&rotation);
    Pose {
        position: Point {
            x: x.trans.x,
            y: x.trans.y,
            z: x.trans.z,
        },
        orientation: Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::params::Settings;
    use spatial_dynamics_core::algorithms::{frame_jacobian, frame_placement};

    /// The answer's columns follow the request's joint order (the base's six first), its
    /// Jacobians are the library's with columns so permuted, its poses the library's placements
    /// as quaternions; a bad link or reference fails the request with empty arrays.
    #[test]
    fn answers_in_the_request_order_and_refuses_bad_requests() {
        let mut settings = Settings::default();
        settings.apply_arg("floating_base", "true").unwrap();
        let mut engine = Engine::from_settings(&settings, None).unwrap();
        let mut names = engine.names().to_vec();
        names.reverse();
        let position: Vec<f64> = (0..names.len()).map(|k| 0.3 - 0.2 * k as f64).collect();
        let base_pose = Pose {
            position: Point {
                x: 0.5,
                y: -1.0,
                z: 2.0,
            },
            orientation: Quaternion {
                x: 0.0,
                y: 0.6,
                z: 0.0,
                w: 0.8,
            },
        };
        let request = FrameKinematicsRequest {
            name: names.clone(),
            position: position.clone(),
            base_pose: base_pose.clone(),
            links: vec!["tool0".into(), "link3".into()],
            reference: "local".into(),
            ..Default::default()
        };
        let r = engine.frame_kinematics(&request);
        assert!(r.success, "{}", r.message);
        let n = r.columns.len();
        assert_eq!(n, engine.model.nv());
        assert_eq!(
            r.columns[..6]
                .iter()
                .filter(|c| c.ends_with("/linear_x"))
                .count(),
            1
        );
        assert_eq!(r.columns[6..], names[..]);
        assert_eq!(r.jacobians.len(), 2 * 6 * n);
        // Our q: the base pose, then each joint where the request put it.
        let mut q = vec![0.0; engine.model.nq()];
        q[..7].copy_from_slice(&[0.5, -1.0, 2.0, 0.0, 0.6, 0.0, 0.8]);
        let v_index: Vec<usize> = (0..6)
            .chain(names.iter().map(|name| {
                let j = engine
                    .model
                    .coordinate_joints()
                    .find(|j| j.name == name)
                    .unwrap();
                j.v_index
            }))
            .collect();
        for (name, p) in names.iter().zip(&position) {
            let j = engine
                .model
                .coordinate_joints()
                .find(|j| j.name == name)
                .unwrap();
            q[j.q_index] = *p;
        }
        let (model, ws) = (&engine.model, &mut engine.ws);
        for (l, link) in request.links.iter().enumerate() {
            let frame = find_frame(model, link).unwrap();
            let x = frame_placement(model, ws, &q, &frame).unwrap();
            let o = &r.poses[l].orientation;
            let got =
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(o.w, o.x, o.y, o.z));
            assert!((got.to_rotation_matrix().matrix() - x.rot.transpose()).amax() < 1e-14);
            assert!((r.poses[l].position.x - x.trans.x).abs() < 1e-14);
            let j = frame_jacobian(model, ws, &q, &frame, ReferenceFrame::Local).unwrap();
            for row in 0..6 {
                for (c, &k) in v_index.iter().enumerate() {
                    assert_eq!(r.jacobians[(l * 6 + row) * n + c], j[(row, k)]);
                }
            }
        }
        assert!(r.mass > 0.0 && r.center_of_mass_jacobian.len() == 3 * n);
        for (bad, says) in [
            (
                FrameKinematicsRequest {
                    links: vec!["tool0".into(), "nope".into()],
                    ..request.clone()
                },
                "links[1]: the model has no link named 'nope'",
            ),
            (
                FrameKinematicsRequest {
                    reference: "body".into(),
                    ..request.clone()
                },
                "reference: unknown reference 'body'",
            ),
            (
                FrameKinematicsRequest {
                    position: position[1..].to_vec(),
                    ..request.clone()
                },
                "position",
            ),
        ] {
            let r = engine.frame_kinematics(&bad);
            assert!(!r.success && r.message.contains(says), "{}", r.message);
            assert!(
                r.links.is_empty()
                    && r.poses.is_empty()
                    && r.jacobians.is_empty()
                    && r.columns.is_empty()
            );
        }
    }
}
