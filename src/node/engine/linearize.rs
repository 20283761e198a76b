//! `~/linearize`: the state-space `A`, `B` of `x = [q; v]`, `u = τ` at the state a request
//! gives (see `msg/srv/Linearize.srv`), in continuous time or over one semi-implicit Euler step,
//! from the library's [`linearize`].
//!
//! The state is read as for `~/forward_dynamics` (joint arrays by name, the floating base from
//! `base_pose` and `base_twist`); an empty `effort` linearises at `τ = ID(q, v, 0)`, the efforts
//! that hold the state still. Every matrix is answered row-major over the velocity coordinates
//! in answer order: a floating base's six first, then the joints as the request named them.

use super::requests::{Refused, NOT_FINITE};
use super::Engine;
use crate::ros::msgs::{LinearizeRequest, LinearizeResponse};
use nalgebra::DMatrix;
use spatial_dynamics_core::algorithms::{bias, linearize, Linearization};
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
        } else {
            self.read_efforts(&req.effort, &req.base_wrench)?;
        }
        let (index, columns) = self.velocity_columns();
        let model = &self.model;
        let linearization = self
            .linearization
            .get_or_insert_with(|| Linearization::new(model));
        let d = linearize(
            &self.model,
            &mut self.ws,
            &self.q,
            &self.v,
            &self.tau,
            req.dt,
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
            Some(_) => {
                let joint = &self.model.bodies()[0].joint.name;
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

/// `m`'s entries at `rows` × `columns`, row-major.
pub(super) fn permuted(m: &DMatrix<f64>, rows: &[usize], columns: &[usize]) -> Vec<f64> {
    rows.iter()
        .flat_map(|&r| columns.iter().map(move |&c| m[(r, c)]))
        .collect()
}
