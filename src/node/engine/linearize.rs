//! `~/linearize`: the state-space `A`, `B` of `x = [q; v]`, `u = τ` at the state a request
//! gives (see `msg/srv/Linearize.srv`), in continuous time or over one semi-implicit Euler step,
//! from the library's [`linearize_with_passive`].
//!
//! The state is read as for `~/forward_dynamics` (joint arrays by name, the floating base from
//! `base_pose` and `base_twist`). In serve mode the dynamics are the model's own, and an empty
//! `effort` linearises at `τ = ID(q, v, 0)`, the efforts that hold the state still. In simulate
//! mode they are the simulator's, with the passive joint forces of its `passive` parameter,
//! `q̈ = FD(q, v, clamp(τ) + τ_p(q, v))`, and an empty `effort` is the command
//! `τ = ID(q, v, 0) − τ_p(q, v)` whose total effort holds the state still (refused, naming the
//! joint, where that command is beyond an effort limit the simulator clamps). Every matrix is
//! answered row-major over the velocity coordinates in answer order: a floating base's six
//! first, then the joints as the request named them.

use super::requests::{Refused, NOT_FINITE};
use super::Engine;
use crate::ros::msgs::{LinearizeRequest, LinearizeResponse};
use nalgebra::DMatrix;
use spatial_dynamics_core::algorithms::{bias, linearize_with_passive, Linearization};
use spatial_dynamics_core::sim::{Passive, PassiveForces};
use spatial_dynamics_core::Externals;

impl Engine {
    /// `~/linearize`.
    pub fn linearize(&mut self, req: &LinearizeRequest) -> LinearizeResponse {
        self.linearize_of(req)
            .unwrap_or_else(LinearizeResponse::refused)
    }

    fn linearize_of(&mut self, req: &LinearizeRequest) -> Result<LinearizeResponse, String> {
        self.read_request_state(req)?;
        if req.effort.is_empty() {
            // ID(q, v, 0) is the bias C(q, v).
            let tau = bias(
                &self.model,
                &mut self.ws,
                &self.q,
                &self.v,
                &Externals::none(),
            )
            .map_err(|e| e.to_string())?;
            self.tau.copy_from_slice(tau);
            if let Some((forces, on)) = self
                .simulation
                .as_ref()
                .map(|s| s.simulator().passive_forces())
            {
                if let Err(vi) = holding_command(forces, on, &self.q, &self.v, &mut self.tau) {
                    let (index, columns) = self.velocity_columns();
                    let name =
                        (index.iter().position(|&i| i == vi)).map_or("a joint", |c| &columns[c]);
                    return Err(format!(
                        "the effort that holds the state still is beyond {name}'s effort \
                         limit: give the efforts to linearise at"
                    ));
                }
            }
        } else {
            self.read_efforts(&req.effort, &req.base_wrench)?;
        }
        let passive = self
            .simulation
            .as_ref()
            .map(|s| s.simulator().passive_forces());
        let (index, columns) = self.velocity_columns();
        let model = &self.model;
        let linearization = self
            .linearization
            .get_or_insert_with(|| Linearization::new(model));
        let d = linearize_with_passive(
            &self.model,
            &mut self.ws,
            &self.q,
            &self.v,
            &self.tau,
            req.dt,
            passive,
            linearization,
        )
        .map_err(|e| e.to_string())?;
        let ddq_dq = permuted(d.ddq_dq, &index, &index);
        let ddq_dv = permuted(d.ddq_dv, &index, &index);
        let minv = permuted(d.minv, &index, &index);
        // A's and B's rows (and A's columns): δq then δv, each in answer order.
        let nv = index.len();
        let state: Vec<usize> = index
            .iter()
            .copied()
            .chain(index.iter().map(|&i| nv + i))
            .collect();
        let response = LinearizeResponse {
            success: true,
            message: String::new(),
            dt: req.dt,
            effort: index.iter().map(|&i| self.tau[i]).collect(),
            acceleration: index.iter().map(|&i| self.ws.qdd()[i]).collect(),
            a: permuted(linearization.a(), &state, &state),
            b: permuted(linearization.b(), &state, &index),
            ddq_dq,
            ddq_dv,
            minv,
            columns,
        };
        let numbers = [
            &response.effort,
            &response.acceleration,
            &response.a,
            &response.b,
        ];
        if !numbers
            .iter()
            .chain([&response.ddq_dq, &response.ddq_dv, &response.minv].iter())
            .all(|x| x.iter().all(|x| x.is_finite()))
        {
            return Err(NOT_FINITE.into());
        }
        Ok(response)
    }
}

impl Engine {
    /// The velocity coordinates in answer order, as model indices, and their names: a floating
    /// base's six first, `<base joint>/linear_x` … `<base joint>/angular_z`, then the joints in
    /// the order the request named them (or the model's).
    pub(super) fn velocity_columns(&self) -> (Vec<usize>, Vec<String>) {
        let base = self.map.base().map(|(_, v)| v..v + 6).into_iter().flatten();
        let index = base
            .chain(self.map.answer_order().map(|s| self.map.slot(s).1))
            .collect();
        let mut columns: Vec<String> = match self.map.base() {
            Some((_, v)) => {
                // The floating joint: a root body's, whichever body of the tree it is.
                let joint = (self.model.bodies().iter())
                    .find(|b| b.parent.is_none() && b.joint.coords.v_index == v)
                    .map_or("base", |b| b.joint.name.as_str());
                BASE_COLUMNS
                    .iter()
                    .map(|c| format!("{joint}/{c}"))
                    .collect()
            }
            None => Vec::new(),
        };
        columns.extend(self.map.answer_names());
        (index, columns)
    }
}

/// The names of a floating base's six velocity coordinates, after its joint's name.
const BASE_COLUMNS: [&str; 6] = [
    "linear_x",
    "linear_y",
    "linear_z",
    "angular_x",
    "angular_y",
    "angular_z",
];

/// `tau = ID(q, v, 0) − τ_p(q, v)`, from `tau = ID(q, v, 0)`: the command whose total effort
/// `clamp(τ) + τ_p` ([`PassiveForces::total`]) is `ID(q, v, 0)`, holding the state still under
/// the passive forces `on`. Where that command is beyond its joint's effort limit (with
/// `on.effort_limits`) no command holds the state still: the error is that velocity index.
fn holding_command(
    forces: &PassiveForces,
    on: &Passive,
    q: &[f64],
    v: &[f64],
    tau: &mut [f64],
) -> Result<(), usize> {
    let nv = tau.len();
    let (zero, mut passive) = (vec![0.0; nv], vec![0.0; nv]);
    forces.total(on, q, v, &zero, &mut passive);
    for (tau, p) in tau.iter_mut().zip(&passive) {
        *tau -= p;
    }
    let mut clamped = vec![0.0; nv];
    forces.clamp_efforts(on, tau, &mut clamped);
    match (0..nv).find(|&i| clamped[i] != tau[i]) {
        Some(i) => Err(i),
        None => Ok(()),
    }
}

/// `m`'s entries at `rows` × `columns`, row-major.
pub(super) fn permuted(m: &DMatrix<f64>, rows: &[usize], columns: &[usize]) -> Vec<f64> {
    rows.iter()
        .flat_map(|&r| columns.iter().map(move |&c| m[(r, c)]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::params::Settings;

    /// The floating joint listed after a fixed-base arm in the URDF: the base's six columns
    /// carry the floating joint's name, and a bad wrench names geometry_msgs/Wrench's fields.
    #[test]
    fn base_columns_name_the_floating_joint_and_a_bad_wrench_its_field() {
        let inertial = r#"<inertial><mass value="1"/><inertia ixx="0.02" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.015"/></inertial>"#;
        let urdf = format!(
            r#"<robot name="two_roots"><link name="world"/>
            <link name="arm">{inertial}</link><link name="box">{inertial}</link><link name="lid">{inertial}</link>
            <joint name="j_arm" type="revolute"><parent link="world"/><child link="arm"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
            <joint name="free" type="floating"><parent link="world"/><child link="box"/><origin xyz="1 0 0"/></joint>
            <joint name="hinge" type="revolute"><parent link="box"/><child link="lid"/><axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="10" velocity="1"/></joint>
            </robot>"#
        );
        let settings = Settings {
            robot_description: urdf,
            ..Settings::default()
        };
        let mut engine = Engine::from_settings(&settings, None).unwrap();
        let names = vec!["j_arm".to_string(), "hinge".to_string()];
        let mut req = LinearizeRequest {
            name: names.clone(),
            position: vec![0.1, 0.2],
            velocity: vec![0.0, 0.0],
            ..Default::default()
        };
        let answer = engine.linearize(&req);
        assert!(answer.success, "{}", answer.message);
        let base: Vec<String> = BASE_COLUMNS.iter().map(|c| format!("free/{c}")).collect();
        assert_eq!(answer.columns[..6], base[..]);
        assert_eq!(answer.columns[6..], names[..]);
        req.effort = vec![0.0, 0.0];
        req.base_wrench.torque.z = f64::INFINITY;
        let answer = engine.linearize(&req);
        assert_eq!(answer.message, "base_wrench.torque.z is inf");
    }

    /// One damped joint (`d = 0.5`): in simulate mode with `passive: [damping]` the continuous
    /// `∂q̈/∂q̇` is `−d H⁻¹` and an empty effort holds the state still (`q̈ = 0`); in serve mode
    /// `∂q̈/∂q̇` is the model's own, zero for one joint.
    #[test]
    fn simulate_mode_linearises_with_the_simulators_passive_forces() {
        let urdf = r#"<robot name="damped"><link name="world"/>
            <link name="rod"><inertial><origin xyz="0 0 -0.5"/><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.01"/></inertial></link>
            <joint name="j" type="revolute"><parent link="world"/><child link="rod"/><axis xyz="0 1 0"/>
            <limit lower="-3" upper="3" effort="100" velocity="10"/><dynamics damping="0.5"/></joint>
            </robot>"#;
        let req = LinearizeRequest {
            name: vec!["j".into()],
            position: vec![0.3],
            velocity: vec![0.2],
            ..Default::default()
        };
        for simulate in [false, true] {
            let settings = Settings {
                robot_description: urdf.into(),
                simulate,
                passive: vec!["damping".into()],
                ..Settings::default()
            };
            let mut engine = Engine::from_settings(&settings, None).unwrap();
            let answer = engine.linearize(&req);
            assert!(answer.success, "{}", answer.message);
            let damping = if simulate { -0.5 * answer.minv[0] } else { 0.0 };
            assert!(
                (answer.a[3] - damping).abs() < 1e-12 && (answer.ddq_dv[0] - damping).abs() < 1e-12,
                "simulate {simulate}: ∂q̈/∂q̇ {} (expected {damping})",
                answer.a[3]
            );
            assert!(
                answer.acceleration[0].abs() < 1e-12,
                "{:?}",
                answer.acceleration
            );
        }
    }

    /// A rod whose gravity torque at the state (`2 · 9.81 · 0.5 · sin 0.3` ≈ 2.9 N·m) is beyond
    /// its 1 N·m effort limit: in simulate mode with `passive: [effort_limits]` no command holds
    /// it still, so an empty effort is refused naming the joint, and given efforts are still
    /// answered; in serve mode (nothing clamped) the empty effort is answered.
    #[test]
    fn a_holding_effort_beyond_the_effort_limit_is_refused_naming_the_joint() {
        let urdf = r#"<robot name="weak"><link name="world"/>
            <link name="rod"><inertial><origin xyz="0 0 -0.5"/><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.01"/></inertial></link>
            <joint name="weak_joint" type="revolute"><parent link="world"/><child link="rod"/><axis xyz="0 1 0"/>
            <limit lower="-3" upper="3" effort="1" velocity="10"/></joint>
            </robot>"#;
        let req = LinearizeRequest {
            name: vec!["weak_joint".into()],
            position: vec![0.3],
            velocity: vec![0.0],
            ..Default::default()
        };
        for simulate in [false, true] {
            let settings = Settings {
                robot_description: urdf.into(),
                simulate,
                passive: vec!["effort_limits".into()],
                ..Settings::default()
            };
            let mut engine = Engine::from_settings(&settings, None).unwrap();
            let answer = engine.linearize(&req);
            if simulate {
                assert!(!answer.success);
                assert!(
                    answer.message.contains("weak_joint's effort limit"),
                    "{}",
                    answer.message
                );
                let given = LinearizeRequest {
                    effort: vec![0.5],
                    ..req.clone()
                };
                let answer = engine.linearize(&given);
                assert!(answer.success, "{}", answer.message);
            } else {
                assert!(answer.success, "{}", answer.message);
                assert!(answer.effort[0].abs() > 2.0, "{:?}", answer.effort);
            }
        }
    }
}
