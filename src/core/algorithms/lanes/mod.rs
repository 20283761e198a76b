//! RNEA on many states of one model at once: [`rnea_rows`] runs blocks of [`LANES`] states
//! through passes in which every `f64` of the scalar kernel is a lane value holding one state's
//! (structure of arrays), so that each arithmetic instruction is a packed SSE2 operation on
//! [`LANES`] states where the scalar kernel moves a 3-vector as a pair and a single. Every
//! branch of the passes is on the model (joint kind, unit axis, transform form), the same for
//! every state, so the lanes never diverge.
//!
//! Each lane computes exactly the scalar [`rnea`]'s operations in its order (no fused
//! multiply-add, no reassociation): its `τ` has the same bits. The modules: the lane value and
//! its 3-vectors (`value`), the lane forms of the spatial quantities and transforms RNEA uses
//! (`spatial`), and the passes (`passes`).

mod passes;
pub(crate) mod spatial;
mod value;

use super::rnea::rnea;
use super::validate::all_finite;
use crate::error::{check_len, DynamicsError};
use crate::model::{JointKind, Model};
use crate::Workspace;
use passes::{lane_column, rnea_lanes};
use spatial::{LaneForce, LaneInertia, LaneMotion, LaneTransform};
use value::{Lanes, V3};

/// States per block of [`rnea_rows`]: two, one SSE2 register of `f64`.
pub const LANES: usize = 2;

/// `τ = RNEA(q, q̇, q̈)` (gravity, base at rest, no external wrenches) for each of many states:
/// row `r` of `q_rows` (`nq` values a row), `v_rows` and `a_rows` (`nv` each) is state `r`,
/// and its `τ` goes to row `r` of `tau_rows`, bit for bit what [`rnea`] gives on that state.
///
/// On a model whose every joint is revolute or prismatic (most arms: UR5, Panda, Kinova; mimic
/// joints too) blocks of [`LANES`] rows run at once (the
/// module's passes) and the remaining rows one at a time; any other model runs every row
/// through [`rnea`]. A block with a non-finite input or result runs again row by row through
/// [`rnea`], so an error is [`rnea`]'s, naming the joint or field. Errors come with the index
/// of the first row that fails (0 for a foreign workspace or rows of the wrong length). The
/// lane scratch lives in the workspace: nothing is allocated.
pub fn rnea_rows(
    model: &Model,
    ws: &mut Workspace,
    q_rows: &[f64],
    v_rows: &[f64],
    a_rows: &[f64],
    tau_rows: &mut [f64],
) -> Result<(), (usize, DynamicsError)> {
    ws.check(model).map_err(|e| (0, e))?;
    let (nq, nv) = (model.nq, model.nv);
    let rows = q_rows.len() / nq.max(1);
    let lengths = [
        ("q rows", nq, q_rows.len()),
        ("v rows", nv, v_rows.len()),
        ("a rows", nv, a_rows.len()),
        ("tau rows", nv, tau_rows.len()),
    ];
    for (vector, per_row, got) in lengths {
        check_len(vector, rows * per_row, got).map_err(|e| (0, e))?;
    }
    let mut first = 0;
    if ws.lanes.covered {
        while first + LANES <= rows {
            let block = first..first + LANES;
            let (q, v) = (
                &q_rows[nq * first..nq * block.end],
                &v_rows[nv * first..nv * block.end],
            );
            let a = &a_rows[nv * first..nv * block.end];
            let tau = &mut tau_rows[nv * first..nv * block.end];
            let lanes_done = all_finite(q) & all_finite(v) & all_finite(a) && {
                rnea_lanes(model, ws, q, v, a, tau);
                all_finite(tau)
            };
            if !lanes_done {
                rows_one_by_one(model, ws, block, q_rows, v_rows, a_rows, tau_rows)?;
            }
            first += LANES;
        }
    }
    rows_one_by_one(model, ws, first..rows, q_rows, v_rows, a_rows, tau_rows)
}

/// Whether [`rnea_rows`] runs `model`'s states in lanes: every joint is revolute or prismatic,
/// about or along any axis (no planar or floating joint).
pub fn covers(model: &Model) -> bool {
    model
        .bodies
        .iter()
        .all(|b| lane_column(&b.joint.kind).is_some())
}

/// Rows `rows` through the scalar [`rnea`], stopping at the first error (with its row).
fn rows_one_by_one(
    model: &Model,
    ws: &mut Workspace,
    rows: std::ops::Range<usize>,
    q_rows: &[f64],
    v_rows: &[f64],
    a_rows: &[f64],
    tau_rows: &mut [f64],
) -> Result<(), (usize, DynamicsError)> {
    let (nq, nv) = (model.nq, model.nv);
    for r in rows {
        let (q, v) = (&q_rows[nq * r..nq * (r + 1)], &v_rows[nv * r..nv * (r + 1)]);
        let a = &a_rows[nv * r..nv * (r + 1)];
        let tau = rnea(model, ws, q, v, a).map_err(|e| (r, e))?;
        tau_rows[nv * r..nv * (r + 1)].copy_from_slice(tau);
    }
    Ok(())
}

/// The lane passes' scratch and the model's constants in lane form, made with the workspace;
/// empty when the passes do not cover the model (`covered` false).
#[derive(Clone, Debug, Default)]
pub(crate) struct LaneScratch {
    /// Whether every joint is revolute or prismatic ([`covers`]): the lane passes run on it.
    covered: bool,
    /// Each joint's `(j, σ)` when `S = σ e_j` (else unused), and its `S` in every lane when it is
    /// not a unit vector.
    unit_axes: Vec<(usize, f64)>,
    general: Vec<Option<LaneMotion>>,
    /// Whether any `S` is not a unit vector.
    any_general: bool,
    /// A prismatic joint's axis (zero for a turn), in every lane.
    slide_axes: Vec<V3>,
    /// Each body's inertia and joint placement `X_tree`, in every lane.
    inertia: Vec<LaneInertia>,
    x_tree: Vec<LaneTransform>,
    /// The turn angles, their sines and cosines, [`LANES`] a body (body-major).
    angles: Vec<f64>,
    sines: Vec<f64>,
    cosines: Vec<f64>,
    /// The coordinate `μ q + o` of a joint that does not turn about a coordinate axis.
    positions: Vec<Lanes>,
    /// `ⁱX_λ`: the entries the joint's form reads; those constant in `q` set here, from `X_tree`.
    x_up: Vec<LaneTransform>,
    /// Whether a body's velocity and acceleration are read back from `v`, `a`: it is the parent
    /// of a body that does not follow it (a branch); along a chain they stay in registers.
    read_later: Vec<bool>,
    /// Body velocities, accelerations and forces (body coordinates), and `τ` by coordinate.
    v: Vec<LaneMotion>,
    a: Vec<LaneMotion>,
    f: Vec<LaneForce>,
    tau: Vec<Lanes>,
}

impl LaneScratch {
    pub(crate) fn new(model: &Model) -> Self {
        if !covers(model) {
            return Self::default();
        }
        let columns: Vec<_> = model
            .bodies
            .iter()
            .filter_map(|b| lane_column(&b.joint.kind))
            .collect();
        let n = model.nbodies();
        let x_tree: Vec<_> = model
            .bodies
            .iter()
            .map(|b| LaneTransform::splat(&b.x_tree))
            .collect();
        let mut read_later = vec![false; n];
        for (k, body) in model.bodies.iter().enumerate() {
            match body.parent {
                Some(p) if p + 1 != k => read_later[p] = true,
                _ => {}
            }
        }
        LaneScratch {
            covered: true,
            read_later,
            unit_axes: columns.iter().map(|c| c.unwrap_or((0, 0.0))).collect(),
            any_general: columns.iter().any(Result::is_err),
            general: columns
                .iter()
                .map(|c| c.err().map(|s| LaneMotion::splat(&s)))
                .collect(),
            slide_axes: model
                .bodies
                .iter()
                .map(|b| match b.joint.kind {
                    JointKind::Prismatic { axis } => V3::splat(&axis),
                    _ => V3::default(),
                })
                .collect(),
            inertia: model
                .bodies
                .iter()
                .map(|b| LaneInertia::splat(&b.inertia))
                .collect(),
            x_up: x_tree.clone(),
            x_tree,
            angles: vec![0.0; n * LANES],
            sines: vec![0.0; n * LANES],
            cosines: vec![0.0; n * LANES],
            positions: vec![Lanes::default(); n],
            v: vec![LaneMotion::default(); n],
            a: vec![LaneMotion::default(); n],
            f: vec![LaneForce::default(); n],
            tau: vec![Lanes::default(); model.nv],
        }
    }
}
