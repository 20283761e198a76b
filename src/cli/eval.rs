//! `spatial_dynamics eval`: one JSON request per line on stdin, one JSON answer per line on
//! stdout, in order. A bad request answers `{"error": "..."}` and the loop goes on.
//!
//! ```text
//! {"op":"inverse_dynamics","q":[..],"v":[..],"a":[..]}                 → {"tau":[..]}
//! {"op":"forward_dynamics","q":[..],"v":[..],"tau":[..],"method":"aba"} → {"a":[..]}
//! {"op":"mass_matrix","q":[..]}                                          → {"M":[[..],..]}
//! {"op":"gravity","q":[..]}                                              → {"tau":[..]}
//! ```
//! `method` is `aba`, `crba` or `rnea_columns` (default `aba`). Numbers are printed in the
//! shortest form that parses back to the same f64.

use super::ModelArgs;
use serde::Deserialize;
use serde_json::{json, Value};
use spatial_dynamics::algorithms::{crba, forward_dynamics, gravity, rnea};
use spatial_dynamics::{Externals, ForwardDynamicsMethod, Model, Workspace};
use std::io::{BufRead, Write};

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

/// Runs the request loop until stdin closes.
pub fn run(args: &ModelArgs) -> Result<(), String> {
    let model = args.load()?;
    let mut ws = Workspace::new(&model);
    let stdin = std::io::stdin();
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    for line in stdin.lock().lines() {
        let line = line.map_err(|e| format!("reading stdin: {e}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let answer = match serde_json::from_str::<Request>(&line) {
            Ok(request) => {
                answer(&model, &mut ws, request).unwrap_or_else(|e| json!({ "error": e }))
            }
            Err(e) => json!({ "error": format!("bad request: {e}") }),
        };
        writeln!(out, "{answer}")
            .and_then(|_| out.flush())
            .map_err(|e| format!("writing stdout: {e}"))?;
    }
    Ok(())
}

fn answer(model: &Model, ws: &mut Workspace, request: Request) -> Result<Value, String> {
    let text = |e: spatial_dynamics::DynamicsError| e.to_string();
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
