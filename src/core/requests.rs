//! JSON requests answered with JSON: the request handling behind `spatial_dynamics eval`, kept in
//! the library (no I/O here) so that it can be tested and fuzzed on its own.
//!
//! ```text
//! {"op":"inverse_dynamics","q":[..],"v":[..],"a":[..]}                 → {"tau":[..]}
//! {"op":"forward_dynamics","q":[..],"v":[..],"tau":[..],"method":"aba"} → {"a":[..]}
//! {"op":"mass_matrix","q":[..]}                                          → {"M":[[..],..]}
//! {"op":"gravity","q":[..]}                                              → {"tau":[..]}
//! {"op":"frame_placement","q":[..],"frame":"LINK"}
//!     → {"translation":[x,y,z],"rotation":[[r00,r01,r02],[r10,r11,r12],[r20,r21,r22]]}
//! {"op":"frame_jacobian","q":[..],"frame":"LINK","reference":"world"}  → {"J":[[..nv..] × 6]}
//! {"op":"frame_acceleration","q":[..],"v":[..],"a":[..],"frame":"LINK","reference":"local"}
//!     → {"acceleration":[6]}
//! {"op":"center_of_mass","q":[..]}                → {"mass":m,"com":[x,y,z],"J":[[..nv..] × 3]}
//! {"op":"inverse_dynamics_derivatives","q":[..],"v":[..],"a":[..]}
//!     → {"dtau_dq":[[..nv..] × nv],"dtau_dv":[[..nv..] × nv],"M":[[..nv..] × nv]}
//! {"op":"forward_dynamics_derivatives","q":[..],"v":[..],"tau":[..]}
//!     → {"ddq_dq":[[..nv..] × nv],"ddq_dv":[[..nv..] × nv],"Minv":[[..nv..] × nv]}
//! ```
//! `q`, `v`, `a` and `tau` follow [`Model::coordinate_joints`]; `method` is `aba`, `crba` or
//! `rnea_columns` (default `aba`). A bad request answers `{"error": "..."}` naming the problem.
//!
//! Frames are URDF links ([`find_frame`]): the rotation, by rows, maps link-frame vectors to
//! world ones and the translation is the link origin in the world; Jacobian rows and
//! accelerations are `[linear; angular]`; `reference` is `world`, `local` or
//! `local_world_aligned` ([`ReferenceFrame`]; the classical acceleration takes the last two).
//!
//! Derivative matrices are given by rows (row `i` the derivative of `τ_i` or `q̈_i`), columns in
//! `v` order, with respect to `q` along the tangent `q ⊕ ε e_k` ([`derivatives`](crate::algorithms::derivatives)).

use crate::algorithms::{
    aba_derivatives, center_of_mass_jacobian, crba, find_frame, forward_dynamics,
    frame_classical_acceleration, frame_jacobian, frame_placement, gravity, rnea, rnea_derivatives,
    ReferenceFrame,
};
use crate::{Externals, ForwardDynamicsMethod, Model, Workspace};
use nalgebra::DMatrix;
use serde::Deserialize;
use serde_json::{json, Value};

/// A request, once its fields are checked against its op.
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
    FramePlacement {
        q: Vec<f64>,
        frame: String,
    },
    FrameJacobian {
        q: Vec<f64>,
        frame: String,
        reference: String,
    },
    FrameAcceleration {
        q: Vec<f64>,
        v: Vec<f64>,
        a: Vec<f64>,
        frame: String,
        reference: String,
    },
    CenterOfMass {
        q: Vec<f64>,
    },
    InverseDynamicsDerivatives {
        q: Vec<f64>,
        v: Vec<f64>,
        a: Vec<f64>,
    },
    ForwardDynamicsDerivatives {
        q: Vec<f64>,
        v: Vec<f64>,
        tau: Vec<f64>,
    },
}

/// Every field any request has, read straight from the text (nothing buffered on the way, so
/// a bad value's error carries its line and column, and memory follows the numbers read).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Fields {
    op: String,
    q: Option<Vec<f64>>,
    v: Option<Vec<f64>>,
    a: Option<Vec<f64>>,
    tau: Option<Vec<f64>>,
    method: Option<String>,
    frame: Option<String>,
    reference: Option<String>,
}

/// The ops and the fields each takes (`method` optional, the others required).
const OPS: [(&str, &[&str]); 10] = [
    ("inverse_dynamics", &["q", "v", "a"]),
    ("forward_dynamics", &["q", "v", "tau", "method"]),
    ("mass_matrix", &["q"]),
    ("gravity", &["q"]),
    ("frame_placement", &["q", "frame"]),
    ("frame_jacobian", &["q", "frame", "reference"]),
    ("frame_acceleration", &["q", "v", "a", "frame", "reference"]),
    ("center_of_mass", &["q"]),
    ("inverse_dynamics_derivatives", &["q", "v", "a"]),
    ("forward_dynamics_derivatives", &["q", "v", "tau"]),
];

impl Fields {
    /// The request these fields make for their op: every field it needs, none it does not take.
    fn request(self) -> Result<Request, String> {
        let Some((op, takes)) = OPS.iter().find(|(name, _)| *name == self.op) else {
            let names: Vec<&str> = OPS.iter().map(|(name, _)| *name).collect();
            return Err(format!(
                "unknown op '{}' (one of: {})",
                self.op,
                names.join(", ")
            ));
        };
        let present = [
            ("q", self.q.is_some()),
            ("v", self.v.is_some()),
            ("a", self.a.is_some()),
            ("tau", self.tau.is_some()),
            ("method", self.method.is_some()),
            ("frame", self.frame.is_some()),
            ("reference", self.reference.is_some()),
        ];
        if let Some((extra, _)) = present
            .iter()
            .find(|(name, given)| *given && !takes.contains(name))
        {
            return Err(format!(
                "op {op} takes no field '{extra}' (its fields: {})",
                takes.join(", ")
            ));
        }
        fn need<T>(field: Option<T>, name: &str, op: &str) -> Result<T, String> {
            field.ok_or_else(|| format!("op {op} needs field '{name}'"))
        }
        let q = need(self.q, "q", op)?;
        Ok(match *op {
            "inverse_dynamics" => Request::InverseDynamics {
                q,
                v: need(self.v, "v", op)?,
                a: need(self.a, "a", op)?,
            },
            "forward_dynamics" => Request::ForwardDynamics {
                q,
                v: need(self.v, "v", op)?,
                tau: need(self.tau, "tau", op)?,
                method: self.method,
            },
            "mass_matrix" => Request::MassMatrix { q },
            "gravity" => Request::Gravity { q },
            "frame_placement" => Request::FramePlacement {
                q,
                frame: need(self.frame, "frame", op)?,
            },
            "frame_jacobian" => Request::FrameJacobian {
                q,
                frame: need(self.frame, "frame", op)?,
                reference: need(self.reference, "reference", op)?,
            },
            "frame_acceleration" => Request::FrameAcceleration {
                q,
                v: need(self.v, "v", op)?,
                a: need(self.a, "a", op)?,
                frame: need(self.frame, "frame", op)?,
                reference: need(self.reference, "reference", op)?,
            },
            "center_of_mass" => Request::CenterOfMass { q },
            "inverse_dynamics_derivatives" => Request::InverseDynamicsDerivatives {
                q,
                v: need(self.v, "v", op)?,
                a: need(self.a, "a", op)?,
            },
            _ => Request::ForwardDynamicsDerivatives {
                q,
                v: need(self.v, "v", op)?,
                tau: need(self.tau, "tau", op)?,
            },
        })
    }
}

/// The answer to one request line (UTF-8 JSON): the result, or `{"error": "..."}`. Never panics.
pub fn answer_line(model: &Model, ws: &mut Workspace, line: &[u8]) -> Value {
    match parse(line) {
        Ok(request) => answer(model, ws, request).unwrap_or_else(|e| json!({ "error": e })),
        Err(e) => json!({ "error": format!("bad request: {e}") }),
    }
}

/// A request line: one JSON object with an `op` and that op's fields.
fn parse(line: &[u8]) -> Result<Request, String> {
    if line.iter().find(|b| !b.is_ascii_whitespace()) != Some(&b'{') {
        return Err("a request is one JSON object with an \"op\" field".into());
    }
    let fields: Fields = serde_json::from_slice(line).map_err(|e| e.to_string())?;
    fields.request()
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
        Request::MassMatrix { q } => json!({ "M": rows(crba(model, ws, &q).map_err(text)?) }),
        Request::Gravity { q } => json!({ "tau": gravity(model, ws, &q).map_err(text)? }),
        Request::FramePlacement { q, frame } => {
            let frame = find_frame(model, &frame).map_err(text)?;
            let x = frame_placement(model, ws, &q, &frame).map_err(text)?;
            // `x.rot` maps world coordinates to link ones: its columns are the rows of R.
            let rotation: Vec<Vec<f64>> = x
                .rot
                .column_iter()
                .map(|c| c.iter().copied().collect())
                .collect();
            json!({ "translation": x.trans.as_slice(), "rotation": rotation })
        }
        Request::FrameJacobian {
            q,
            frame,
            reference,
        } => {
            let (frame, reference) = (find_frame(model, &frame).map_err(text)?, reference.parse()?);
            json!({ "J": rows(frame_jacobian(model, ws, &q, &frame, reference).map_err(text)?) })
        }
        Request::FrameAcceleration {
            q,
            v,
            a,
            frame,
            reference,
        } => {
            let (frame, reference) = (
                find_frame(model, &frame).map_err(text)?,
                reference.parse::<ReferenceFrame>()?,
            );
            let m = frame_classical_acceleration(model, ws, &q, &v, &a, &frame, reference)
                .map_err(text)?;
            let acceleration: Vec<f64> = m.lin.iter().chain(m.ang.iter()).copied().collect();
            json!({ "acceleration": acceleration })
        }
        Request::CenterOfMass { q } => {
            let (com, j) = center_of_mass_jacobian(model, ws, &q).map_err(text)?;
            json!({ "mass": com.mass, "com": com.position.as_slice(), "J": rows(j) })
        }
        Request::InverseDynamicsDerivatives { q, v, a } => {
            let d = rnea_derivatives(model, ws, &q, &v, &a).map_err(text)?;
            json!({ "dtau_dq": rows(d.dtau_dq), "dtau_dv": rows(d.dtau_dv), "M": rows(d.mass_matrix) })
        }
        Request::ForwardDynamicsDerivatives { q, v, tau } => {
            let d = aba_derivatives(model, ws, &q, &v, &tau, &Externals::none()).map_err(text)?;
            json!({ "ddq_dq": rows(d.ddq_dq), "ddq_dv": rows(d.ddq_dv), "Minv": rows(d.minv) })
        }
    })
}

/// A matrix as a list of its rows.
fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}
