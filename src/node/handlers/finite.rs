//! Messages that leave the node: none may carry a non-finite number (NaN, ±∞).

use crate::ros::msgs::*;

/// A message whose numbers can be checked.
pub trait Finite {
    /// The first field holding a non-finite number (`"effort[2] (joint 'elbow')"`), if any.
    fn non_finite(&self) -> Option<String>;
}

/// `name[i]` for the first non-finite `x[i]`.
fn field(name: &str, x: &[f64]) -> Option<String> {
    let i = x.iter().position(|v| !v.is_finite())?;
    Some(format!("{name}[{i}]"))
}

fn vector(name: &str, v: &Vector3) -> Option<String> {
    field(name, &[v.x, v.y, v.z])
}

impl Finite for JointState {
    fn non_finite(&self) -> Option<String> {
        [
            ("position", &self.position),
            ("velocity", &self.velocity),
            ("effort", &self.effort),
        ]
        .into_iter()
        .find_map(|(name, x)| {
            let i = x.iter().position(|v| !v.is_finite())?;
            Some(match self.name.get(i) {
                Some(joint) => format!("{name}[{i}] (joint '{joint}')"),
                None => format!("{name}[{i}]"),
            })
        })
    }
}

impl Finite for JointDynamics {
    fn non_finite(&self) -> Option<String> {
        field("position", &self.position)
            .or_else(|| field("velocity", &self.velocity))
            .or_else(|| field("acceleration", &self.acceleration))
            .or_else(|| field("effort", &self.effort))
    }
}

impl Finite for Odometry {
    fn non_finite(&self) -> Option<String> {
        let (p, o, t) = (
            &self.pose.pose.position,
            &self.pose.pose.orientation,
            &self.twist.twist,
        );
        field("pose.position", &[p.x, p.y, p.z])
            .or_else(|| field("pose.orientation", &[o.x, o.y, o.z, o.w]))
            .or_else(|| vector("twist.linear", &t.linear))
            .or_else(|| vector("twist.angular", &t.angular))
    }
}

impl Finite for Float64MultiArray {
    fn non_finite(&self) -> Option<String> {
        field("data", &self.data)
    }
}

impl Finite for InverseDynamicsResponse {
    fn non_finite(&self) -> Option<String> {
        let w = &self.base_wrench;
        field("effort", &self.effort)
            .or_else(|| vector("base_wrench.force", &w.force))
            .or_else(|| vector("base_wrench.torque", &w.torque))
    }
}

impl Finite for ForwardDynamicsResponse {
    fn non_finite(&self) -> Option<String> {
        field("acceleration", &self.acceleration)
    }
}

impl Finite for MassMatrixResponse {
    fn non_finite(&self) -> Option<String> {
        field("matrix", &self.matrix)
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
        assert!(js.non_finite().is_none());
        for field in 0..3 {
            let mut bad = js.clone();
            [&mut bad.position, &mut bad.velocity, &mut bad.effort][field][0] = f64::NAN;
            assert!(bad.non_finite().is_some(), "field {field}");
        }
        let mut odom = Odometry::default();
        odom.pose.pose.orientation.w = 1.0;
        assert!(odom.non_finite().is_none());
        odom.twist.twist.angular.z = f64::INFINITY;
        assert!(odom.non_finite().is_some());
        let mut id = InverseDynamicsResponse::default();
        assert!(id.non_finite().is_none());
        id.base_wrench.torque.y = f64::NEG_INFINITY;
        assert!(id.non_finite().is_some());
        assert_eq!(id.non_finite().unwrap(), "base_wrench.torque[1]");
        let mut named = js.clone();
        named.name = vec!["a".into(), "b".into()];
        named.position[1] = f64::INFINITY;
        assert_eq!(named.non_finite().unwrap(), "position[1] (joint 'b')");
    }
}
