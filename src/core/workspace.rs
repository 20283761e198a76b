//! Scratch buffers for the algorithms (Pinocchio's `Data`): sized once from a model, reused by
//! every call so that no call allocates.

use crate::algorithms::derivatives::DerivativeScratch;
use crate::algorithms::frames::FrameScratch;
use crate::algorithms::lanes::LaneScratch;
use crate::error::DynamicsError;
use crate::model::{JointKind, Model, MotionSubspace};
use crate::plan::Plan;
use crate::spatial::{Force, Inertia, Matrix6, Motion, Transform, Vector3};
use crate::InstructionSet;
use nalgebra::{DMatrix, DVector};

/// Every intermediate quantity of the algorithms, per body and per coordinate. Quantities per
/// body are expressed in that body's frame.
#[derive(Clone, Debug)]
pub struct Workspace {
    /// The identity of the model the workspace was made for ([`Workspace::check`]) and its
    /// robot name, for the error.
    model_id: u64,
    model_name: String,
    /// The model's plan: the choices every call follows, made once ([`Plan::new`]).
    pub(crate) plan: Plan,
    /// The joint's own position coordinates (a mimic follower's computed from its leader), for
    /// every joint but those of `turn_axes`, whose one coordinate is read into its turn angle.
    pub(crate) q_joint: Vec<[f64; 7]>,
    /// Each joint's turn angle (`σ q` for a revolute joint about a coordinate axis `σ e_k`,
    /// else 0), its sine and its cosine.
    pub(crate) turn_angles: Vec<f64>,
    pub(crate) turn_sines: Vec<f64>,
    pub(crate) turn_cosines: Vec<f64>,
    /// `ⁱX_λ(i) = X_J(q_i) X_tree,i`: parent body frame → body frame.
    pub(crate) x_up: Vec<Transform>,
    /// `ⁱX_0`: world frame → body frame, from
    /// [`body_placements`](crate::algorithms::kinematics::body_placements) and the frame
    /// algorithms (those of a frame's support only, see
    /// [`FrameScratch`](crate::algorithms::frames::FrameScratch)).
    pub(crate) x_world: Vec<Transform>,
    /// `ⁱX_A`: body `i`'s aligned frame (world axes, origin at an anchor body's origin) → body
    /// frame: the frame of every quantity below said to be in world coordinates (see
    /// `kinematics::update_aligned_placements`).
    pub(crate) x_aligned: Vec<Transform>,
    /// For an anchor, its origin in its parent's aligned frame (in the world for a root).
    pub(crate) anchor_shift: Vec<Vector3>,
    /// Motion subspace `S_i` of each body's joint.
    pub(crate) s: Vec<MotionSubspace>,
    /// Motion subspace `⁰X_i S_i` of each body's joint in world (root) coordinates (CRBA).
    pub(crate) s_world: Vec<MotionSubspace>,
    /// Body spatial velocities `v_i`.
    pub(crate) v: Vec<Motion>,
    /// Body spatial accelerations `a_i` (including the fictitious −g of the base).
    pub(crate) a: Vec<Motion>,
    /// Body spatial velocities in world (root) coordinates (ABA).
    pub(crate) v_world: Vec<Motion>,
    /// Body spatial accelerations in world coordinates, including the fictitious −g (ABA).
    pub(crate) a_world: Vec<Motion>,
    /// Net spatial forces `f_i` transmitted by each body's joint.
    pub(crate) f: Vec<Force>,
    /// Composite rigid-body inertias `I^c_i` (CRBA), in world (root) or body coordinates
    /// (`crba_frames`); in ABA's first pass, each body's own inertia in world coordinates.
    pub(crate) ic: Vec<Inertia>,
    /// World-frame forces `[f_i, f^g_i]` of
    /// [`joint_state_outputs`](crate::algorithms::joint_state_outputs): the inverse-dynamics force
    /// and the gravity force of each body, summed over its subtree by the inward pass.
    pub(crate) f_outputs: Vec<[Force; 2]>,
    /// Articulated-body inertias `I^A_i` (ABA), in world coordinates.
    pub(crate) ia: Vec<Matrix6>,
    /// Articulated bias forces `p^A_i` (ABA), in world coordinates.
    pub(crate) pa: Vec<Force>,
    /// Velocity-product accelerations `c_i = c_J + v_i ×̂ v_J` (ABA), in world coordinates.
    pub(crate) c: Vec<Motion>,
    /// `U_i = I^A_i S_i`, column by column (ABA).
    pub(crate) u: Vec<[Force; 6]>,
    /// `D_i⁻¹ = (S_iᵀ U_i)⁻¹`, in the top-left `nv × nv` block (ABA).
    pub(crate) d_inv: Vec<Matrix6>,
    /// `u_i = τ_i − S_iᵀ p^A_i` (ABA); at a floating root its acceleration `a_i` in world axes,
    /// translations first, and `U_i`, `D_i⁻¹` are not made there
    /// (`aba::articulate_floating_root`).
    pub(crate) u_bias: Vec<[f64; 6]>,
    /// Generalized forces: output of inverse dynamics, bias and gravity.
    pub(crate) tau: DVector<f64>,
    /// Generalized accelerations: output of forward dynamics.
    pub(crate) qdd: DVector<f64>,
    /// `F_c = I^c S_c` for each velocity coordinate `c` (CRBA's column forces, Pinocchio's `Fcrb`),
    /// in world coordinates or, moving up the tree, in each ancestor's.
    pub(crate) f_cols: Vec<Force>,
    /// Joint-space inertia matrix `H` (full, symmetric). Entries outside the tree's sparsity
    /// pattern (coordinate pairs neither of which is an ancestor of the other) are zero from
    /// construction on; every writer keeps them zero.
    pub(crate) mass_matrix: DMatrix<f64>,
    /// Factor of `H` (LTL or Cholesky), kept apart so `mass_matrix` stays readable.
    pub(crate) factor: DMatrix<f64>,
    /// `C(q, q̇)` for forward dynamics.
    pub(crate) bias: DVector<f64>,
    /// Unit acceleration `e_k` (n+1 RNEA method).
    pub(crate) unit: DVector<f64>,
    /// Scratch of the frame algorithms (placements, Jacobians, centre of mass).
    pub(crate) frame_scratch: FrameScratch,
    /// Scratch and results of the derivative algorithms.
    pub(crate) derivatives: DerivativeScratch,
    /// Scratch of RNEA on several states at once ([`rnea_rows`](crate::algorithms::rnea_rows))
    /// and the model's constants in its lane form.
    pub(crate) lanes: LaneScratch,
}

/// The `nv × nv` matrices of `f64` a workspace holds: `H`, its factor, the derivatives' four
/// `∂τ`/`∂q̈` matrices and `M⁻¹`, and their right-hand side of three `nv × nv` blocks.
const SQUARE_MATRICES: usize = 10;
/// Bytes a workspace and its plan hold per body, and per velocity coordinate, besides the
/// square matrices and the plan's lists of ancestors and supports (an upper estimate: about
/// 4 KiB and 100 bytes are used).
const BODY_BYTES: usize = 8 << 10;
const COORDINATE_BYTES: usize = 512;

/// What a workspace for a model takes, by [`Workspace::estimated_bytes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Footprint {
    /// The `nv × nv` matrices: `SQUARE_MATRICES × 8 nv²` bytes.
    pub(crate) matrices: usize,
    /// The plan's lists of each coordinate's ancestors and each body's support: 8 bytes an
    /// entry, the sum of the coordinates' and the bodies' depths (`n²/2` each on a chain).
    pub(crate) lists: usize,
    /// Everything else, per body and per coordinate.
    pub(crate) other: usize,
}

impl Footprint {
    /// The total in bytes.
    pub(crate) fn total(&self) -> usize {
        self.matrices
            .saturating_add(self.lists)
            .saturating_add(self.other)
    }
}

impl Workspace {
    /// The most a model's workspace may take ([`Workspace::estimated_bytes`]): 2 GiB. The model
    /// builder refuses models above it, so that a workspace never exhausts memory. A revolute
    /// chain reaches it at about 4 800 links, any tree at about 5 100 coordinates.
    pub const MAX_BYTES: usize = 2 << 30;

    /// An upper estimate of the bytes [`Workspace::new`] allocates for `model`, counted from the
    /// model's sizes before anything is allocated.
    pub fn estimated_bytes(model: &Model) -> usize {
        Self::footprint(model).total()
    }

    /// [`Workspace::estimated_bytes`], by kind.
    pub(crate) fn footprint(model: &Model) -> Footprint {
        let nv = model.nv;
        let mut depth = vec![0usize; model.nbodies()];
        let mut lists = 0usize;
        for (i, body) in model.bodies.iter().enumerate() {
            depth[i] = body.parent.map_or(1, |p| depth[p] + 1);
            lists = lists.saturating_add(depth[i]);
        }
        if let Some(lambda) = &model.dof_parent {
            let mut dof_depth = vec![0usize; nv];
            for k in 0..nv {
                dof_depth[k] = lambda[k].map_or(0, |p| dof_depth[p] + 1);
                lists = lists.saturating_add(dof_depth[k]);
            }
        }
        Footprint {
            matrices: nv.saturating_mul(nv).saturating_mul(8 * SQUARE_MATRICES),
            lists: lists.saturating_mul(8),
            other: model
                .nbodies()
                .saturating_mul(BODY_BYTES)
                .saturating_add(nv.saturating_mul(COORDINATE_BYTES)),
        }
    }

    /// Buffers sized for `model`.
    pub fn new(model: &Model) -> Self {
        let n = model.nbodies();
        let nv = model.nv;
        Workspace {
            model_id: model.id,
            model_name: model.name.clone(),
            plan: Plan::new(model),
            q_joint: vec![[0.0; 7]; n],
            turn_angles: vec![0.0; n],
            turn_sines: vec![0.0; n],
            turn_cosines: vec![0.0; n],
            x_up: vec![Transform::identity(); n],
            x_world: vec![Transform::identity(); n],
            x_aligned: vec![Transform::identity(); n],
            anchor_shift: vec![Vector3::zeros(); n],
            // A turning or floating joint's S is constant, and `update_joints` leaves it as set
            // here.
            s: model
                .bodies
                .iter()
                .map(|b| {
                    let mut s = MotionSubspace::default();
                    let kind = &b.joint.kind;
                    if kind.turn_axis().is_some() || *kind == JointKind::Floating {
                        kind.jcalc(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], &mut s);
                    }
                    s
                })
                .collect(),
            s_world: vec![MotionSubspace::default(); n],
            v: vec![Motion::zero(); n],
            a: vec![Motion::zero(); n],
            v_world: vec![Motion::zero(); n],
            a_world: vec![Motion::zero(); n],
            f: vec![Force::zero(); n],
            ic: vec![Inertia::zero(); n],
            f_outputs: vec![[Force::zero(); 2]; n],
            ia: vec![Matrix6::zeros(); n],
            pa: vec![Force::zero(); n],
            c: vec![Motion::zero(); n],
            u: vec![[Force::zero(); 6]; n],
            d_inv: vec![Matrix6::zeros(); n],
            u_bias: vec![[0.0; 6]; n],
            tau: DVector::zeros(nv),
            qdd: DVector::zeros(nv),
            f_cols: vec![Force::zero(); nv],
            // From zeroed allocations (calloc): pages are only touched when used, so a model
            // with thousands of coordinates does not spend seconds writing zeros here.
            mass_matrix: DMatrix::from_vec(nv, nv, vec![0.0; nv * nv]),
            factor: DMatrix::from_vec(nv, nv, vec![0.0; nv * nv]),
            bias: DVector::zeros(nv),
            unit: DVector::zeros(nv),
            frame_scratch: FrameScratch::new(model),
            derivatives: DerivativeScratch::new(model),
            lanes: LaneScratch::new(model),
        }
    }

    /// `Ok` when the workspace was made for `model` (or a clone of it), else
    /// [`DynamicsError::ForeignWorkspace`]: every algorithm checks this before it reads the
    /// workspace, one comparison of identities (where Pinocchio's `model.check(data)` compares
    /// sizes, which two models of the same shape share).
    #[inline(always)]
    pub fn check(&self, model: &Model) -> Result<(), DynamicsError> {
        if self.model_id == model.id {
            Ok(())
        } else {
            Err(self.foreign(model))
        }
    }

    #[cold]
    fn foreign(&self, model: &Model) -> DynamicsError {
        DynamicsError::ForeignWorkspace {
            workspace_model: self.model_name.clone(),
            workspace_model_id: self.model_id,
            model: model.name.clone(),
            model_id: model.id,
        }
    }

    /// The instruction set the dispatched passes run in: the fastest this processor runs
    /// ([`InstructionSet::best`]) unless [`set_instruction_set`](Self::set_instruction_set) chose
    /// another. The AVX2 and AVX-512 sets compute the same bits, the baseline the same values
    /// to within rounding ([`crate::instruction_set`]).
    pub fn instruction_set(&self) -> InstructionSet {
        self.plan.instruction_set
    }

    /// Runs the dispatched passes in `set` from now on (benchmarks and tests compare the sets;
    /// [`InstructionSet::Baseline`] gives the bits every x86-64 processor reproduces).
    pub fn set_instruction_set(&mut self, set: InstructionSet) {
        self.plan.instruction_set = set;
    }

    /// The last generalized forces computed (inverse dynamics, bias or gravity).
    pub fn tau(&self) -> &[f64] {
        self.tau.as_slice()
    }

    /// The last generalized accelerations computed (forward dynamics).
    pub fn qdd(&self) -> &[f64] {
        self.qdd.as_slice()
    }

    /// The last joint-space inertia matrix computed.
    pub fn mass_matrix(&self) -> &DMatrix<f64> {
        &self.mass_matrix
    }

    /// Spatial velocity of body `i` in its own frame, from the last pass that computed it.
    pub fn body_velocity(&self, i: usize) -> Motion {
        self.v[i]
    }

    /// Net spatial force `f_i` transmitted to body `i` through its joint, in body `i`
    /// coordinates, from the last inverse-dynamics pass (RNEA, bias or gravity).
    pub fn joint_wrench(&self, i: usize) -> Force {
        self.f[i]
    }

    /// `ⁱX_0` of body `i` (world → body) from the last call that placed it:
    /// [`body_placements`](crate::algorithms::kinematics::body_placements),
    /// [`body_motion`](crate::algorithms::kinematics::body_motion),
    /// [`energy`](crate::algorithms::energy()),
    /// [`joint_jacobians`](crate::algorithms::joint_jacobians) and
    /// [`center_of_mass`](crate::algorithms::center_of_mass()) place every body; a frame's
    /// placement, Jacobian or acceleration only the bodies supporting the frame (a `world`
    /// Jacobian along turns and slides none).
    pub fn world_to_body(&self, i: usize) -> Transform {
        self.x_world[i]
    }

    /// `ⁱX_λ(i)` of body `i` from the last call.
    pub fn parent_to_body(&self, i: usize) -> Transform {
        self.x_up[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::{self, pendulum_urdf};
    use crate::{urdf, ModelOptions};

    /// The estimate counts every `nv × nv` buffer a workspace holds and every entry of the
    /// plan's ancestor and support lists: on a chain (lists of n²/2), a branching tree, a
    /// floating base (six coordinates a body) and mimic joints (no ancestor lists).
    #[test]
    fn the_estimate_counts_the_square_matrices_and_the_lists() {
        let cases = [
            (pendulum_urdf(40, 0.5, 0.7), false),
            (include_str!("tests/models/tree.urdf").to_string(), false),
            (examples::DEFAULT_ARM_URDF.to_string(), true),
            (examples::MIMIC_GRIPPER_URDF.to_string(), false),
        ];
        for (text, floating_base) in cases {
            let options = ModelOptions {
                floating_base,
                ..ModelOptions::default()
            };
            let model = urdf::model_from_str(&text, &options).unwrap();
            let ws = Workspace::new(&model);
            let d = &ws.derivatives;
            let squares = [
                &ws.mass_matrix,
                &ws.factor,
                &d.dtau_dq,
                &d.dtau_dv,
                &d.ddq_dq,
                &d.ddq_dv,
                &d.minv,
            ]
            .iter()
            .map(|m| m.len())
            .sum::<usize>()
                + d.rhs.len();
            let footprint = Workspace::footprint(&model);
            assert_eq!(8 * squares, footprint.matrices, "{}", model.name);
            let lists = ws.plan.supports.entries()
                + ws.plan.dof_ancestors.as_ref().map_or(0, |a| a.entries());
            assert_eq!(8 * lists, footprint.lists, "{}", model.name);
        }
    }
}
