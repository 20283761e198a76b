//! Messages that leave the node: none may carry a non-finite number (NaN, ±∞).

use crate::ros::msgs::*;

/// A message whose numbers can be checked.
pub trait Finite {
    /// Whether every number in the message is finite.
    fn all_finite(&self) -> bool;
}

fn finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

fn finite_vectors(vectors: &[&Vector3]) -> bool {
    vectors.iter().all(|v| finite(&[v.x, v.y, v.z]))
}

impl Finite for JointState {
    fn all_finite(&self) -> bool {
        finite(&self.position) && finite(&self.velocity) && finite(&self.effort)
    }
}

impl Finite for JointDynamics {
    fn all_finite(&self) -> bool {
        finite(&self.position)
            && finite(&self.velocity)
            && finite(&self.acceleration)
            && finite(&self.effort)
    }
}

impl Finite for Odometry {
    fn all_finite(&self) -> bool {
        let (p, o, t) = (
            &self.pose.pose.position,
            &self.pose.pose.orientation,
            &self.twist.twist,
        );
        finite(&[p.x, p.y, p.z, o.x, o.y, o.z, o.w]) && finite_vectors(&[&t.linear, &t.angular])
    }
}

impl Finite for Float64MultiArray {
    fn all_finite(&self) -> bool {
        finite(&self.data)
    }
}

impl Finite for InverseDynamicsResponse {
    fn all_finite(&self) -> bool {
        let w = &self.base_wrench;
        finite(&self.effort) && finite_vectors(&[&w.force, &w.torque])
    }
}

impl Finite for ForwardDynamicsResponse {
    fn all_finite(&self) -> bool {
        finite(&self.acceleration)
    }
}

impl Finite for MassMatrixResponse {
    fn all_finite(&self) -> bool {
        finite(&self.matrix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_non_finite_number_anywhere_fails_the_message() {
        let js = JointState {
            position: vec![0.0, 1.0],
            velocity: vec![2.0],
            effort: vec![3.0],
            ..Default::default()
        };
        assert!(js.all_finite());
        for field in 0..3 {
            let mut bad = js.clone();
            [&mut bad.position, &mut bad.velocity, &mut bad.effort][field][0] = f64::NAN;
            assert!(!bad.all_finite(), "field {field}");
        }
        let mut odom = Odometry::default();
        odom.pose.pose.orientation.w = 1.0;
        assert!(odom.all_finite());
        odom.twist.twist.angular.z = f64::INFINITY;
        assert!(!odom.all_finite());
        let mut id = InverseDynamicsResponse::default();
        assert!(id.all_finite());
        id.base_wrench.torque.y = f64::NEG_INFINITY;
        assert!(!id.all_finite());
    }
}
