//! JSON requests answered with JSON: the request handling behind `spatial_dynamics eval`, kept in
//! the library (no I/O here) so that it can be tested and fuzzed on its own.
//!
//! ```text
//! {"op":"inverse_dynamics","q":[..],"v":[..],"a":[..]}                 → {"tau":[..]}
//! {"op":"forward_dynamics","q":[..],"v":[..],"tau":[..],"method":"aba"} → {"a":[..]}
//! {"op":"mass_matrix","q":[..]}                                          → {"M":[[..],..]}
//! {"op":"gravity","q":[..]}                                              → {"tau":[..]}
//! ```
//! `q`, `v`, `a` and `tau` follow [`Model::coordinate_joints`]; `method` is `aba`, `crba` or
//! `rnea_columns` (default `aba`). A bad request answers `{"error": "..."}` naming the problem.

use crate::algorithms::{crba, forward_dynamics, gravity, rnea};
use crate::{Externals, ForwardDynamicsMethod, Model, Workspace};
use serde::Deserialize;
use serde_json::{json, Value};

#[derive(Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
enum Request {
    InverseDynamics {
        q: Vec<f64>,
        v: Vec<f64>,
        a: Vec<f64>,
    },
    ForwardDynamics {
        q: Vec<f64>,
        v: Vec<f64>,
        tau: Vec<f64>,
        method: Option<String>,
    },
    MassMatrix {
        q: Vec<f64>,
    },
    Gravity {
        q: Vec<f64>,
    },
}

/// The answer to one request line (UTF-8 JSON): the result, or `{"error": "..."}`. Never panics.
pub fn answer_line(model: &Model, ws: &mut Workspace, line: &[u8]) -> Value {
    match serde_json::from_slice::<Request>(line) {
        Ok(request) => answer(model, ws, request).unwrap_or_else(|e| json!({ "error": e })),
        Err(e) => json!({ "error": format!("bad request: {e}") }),
    }
}

fn answer(model: &Model, ws: &mut Workspace, request: Request) -> Result<Value, String> {
    let text = |e: crate::DynamicsError| e.to_string();
    Ok(match request {
        Request::InverseDynamics { q, v, a } => {
            json!({ "tau": rnea(model, ws, &q, &v, &a).map_err(text)? })
        }
        Request::ForwardDynamics { q, v, tau, method } => {
            let method: ForwardDynamicsMethod = method.as_deref().unwrap_or("aba").parse()?;
            json!({ "a": forward_dynamics(model, ws, &q, &v, &tau, method, &Externals::none()).map_err(text)? })
        }
        Request::MassMatrix { q } => {
            let h = crba(model, ws, &q).map_err(text)?;
            let rows: Vec<Vec<f64>> = h.row_iter().map(|r| r.iter().copied().collect()).collect();
            json!({ "M": rows })
        }
        Request::Gravity { q } => json!({ "tau": gravity(model, ws, &q).map_err(text)? }),
    })
}
