//! The robot model: an immutable kinematic tree of rigid bodies (Pinocchio's `Model`,
//! Featherstone's `parent`, `jtype`, `Xtree`, `I`).
//!
//! Bodies are numbered `0..n` in topological order (a parent always comes before its children).
//! Body `i` hangs from its parent (`None`: the fixed root link, i.e. the world) by joint `i`;
//! its frame has the origin of the URDF link it was made from and that link's axes, or those
//! axes turned by quarter turns where that removes the rotation from the joint's placement (the
//! `orientation` module), and every link joined to it by fixed joints is fused into it (their
//! inertias added, their frames kept in [`LinkFrame`]s, which place every link, the body's own
//! included, in the body frame).

mod builder;
pub mod examples;
mod joint;
mod orientation;
mod reduction;
mod spec;

pub use builder::ModelBuilder;
pub use joint::{
    axis_rotation, floating_up, quaternion_rotation, turn_up, turn_up_unrotated, turned, JointKind,
    MotionSubspace, UpShape,
};
pub use spec::{joint_position, BodySpec, JointSpec, ModelOptions};

use crate::error::check_len;
use crate::error::{DynamicsError, ModelError};
use crate::spatial::{Inertia, Transform, Vector3};
use std::sync::atomic::{AtomicU64, Ordering};

/// How a joint's coordinates are found in the model's `q` and `v` vectors.
///
/// The joint's own position is `scale · q[q_index] + offset` (what `jcalc` turns by or slides
/// along). An ordinary joint owns `q[q_index..q_index+nq]` and `v[v_index..v_index+nv]` with
/// `scale = 1`. A mimic follower owns nothing: it reads its leader's coordinate,
/// `q = scale · q_leader + offset`, `q̇ = scale · q̇_leader`, and its effort is projected onto the
/// leader, `τ_leader += scale · Sᵀ f`. The offset is the mimic's (zero for other joints) plus,
/// for a revolute joint, the turn about its own axis that the `orientation` module took out of
/// its placement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoordinateMap {
    /// First position coordinate read by this joint.
    pub q_index: usize,
    /// First velocity coordinate read by this joint.
    pub v_index: usize,
    /// Multiplier applied to the coordinates read.
    pub scale: f64,
    /// Offset added to the (single) position coordinate read.
    pub offset: f64,
}

/// A URDF `<mimic>`: the joint's position is `multiplier · q_leader + offset`.
#[derive(Clone, Debug, PartialEq)]
pub struct Mimic {
    /// The leader joint's name.
    pub leader: String,
    pub multiplier: f64,
    pub offset: f64,
}

/// Position, velocity and effort limits and the joint's `<dynamics>` from URDF (not used by the
/// rigid-body algorithms themselves).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits {
    pub lower: f64,
    pub upper: f64,
    pub velocity: f64,
    pub effort: f64,
    pub damping: f64,
    pub friction: f64,
}

impl Default for JointLimits {
    fn default() -> Self {
        JointLimits {
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            velocity: f64::INFINITY,
            effort: f64::INFINITY,
            damping: 0.0,
            friction: 0.0,
        }
    }
}

/// The joint a body hangs from.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// URDF joint name.
    pub name: String,
    /// What the joint does.
    pub kind: JointKind,
    /// Where its coordinates live.
    pub coords: CoordinateMap,
    /// The `<mimic>` this joint follows, if any (as described; `coords` holds how it reads `q`).
    pub mimics: Option<Mimic>,
    /// Limits and friction from URDF.
    pub limits: JointLimits,
}

impl Joint {
    /// True when the joint reads another joint's coordinate.
    pub fn is_mimic(&self) -> bool {
        self.mimics.is_some()
    }
}

/// A rigid body of the tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// Name of the URDF link the body was made from; the body frame is that link's frame,
    /// possibly turned (its [`LinkFrame`] says how).
    pub name: String,
    /// Parent body, or `None` when the parent is the fixed root link (the world).
    pub parent: Option<usize>,
    /// The joint connecting the parent to this body.
    pub joint: Joint,
    /// `X_tree`: the transform from the parent body's frame to this joint's frame (the joint
    /// placement, a URDF `<origin>` composed with any fused fixed joints before it).
    pub x_tree: Transform,
    /// Spatial inertia in the body frame, with every fused link's inertia added.
    pub inertia: Inertia,
}

/// Where a URDF link ended up: on which body, and how its frame sits in the body frame.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkFrame {
    /// URDF link name.
    pub name: String,
    /// The body carrying the link, or `None` for links fixed to the root (world).
    pub body: Option<usize>,
    /// The transform from the body frame (or the root frame) to the link frame.
    pub x_body_link: Transform,
}

/// What [`ModelOptions::root`](crate::ModelOptions), `tips` and `prune_massless` removed from
/// the description (see the `reduction` module for why each removal is exact).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Reduction {
    /// The link whose subtree was kept, if not the description's root.
    pub root: Option<String>,
    /// The links whose paths from the root were kept (empty: the whole subtree).
    pub tips: Vec<String>,
    /// Moving joints frozen because they lie outside the kept part, with their position (the
    /// `--lock` value given for them, else their neutral position).
    pub frozen_joints: Vec<(String, Vec<f64>)>,
    /// Links that hang from a frozen joint below a kept body: a payload lumped onto it.
    pub payload_links: Vec<String>,
    /// Links that hang from a frozen joint with no kept joint above it: fixed to the world (their
    /// inertia never enters).
    pub removed_links: Vec<String>,
    /// Joints removed because everything below them is massless (with their coordinates).
    pub pruned_joints: Vec<String>,
    /// The links below the pruned joints.
    pub pruned_links: Vec<String>,
}

impl Reduction {
    /// True when nothing was reduced.
    pub fn is_empty(&self) -> bool {
        *self == Reduction::default()
    }

    /// One line per kind of reduction, for `model` and the node's `describe_model`.
    pub fn summary(&self) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(root) = &self.root {
            lines.push(format!("root: '{root}' (its subtree only)"));
        }
        if !self.tips.is_empty() {
            lines.push(format!("tips: {}", self.tips.join(", ")));
        }
        let lists = [
            ("frozen (outside the kept part)", self.frozen_joint_names()),
            (
                "payload lumped onto kept bodies",
                self.payload_links.clone(),
            ),
            (
                "fixed to the world (no kept joint above them)",
                self.removed_links.clone(),
            ),
            ("pruned massless joints", self.pruned_joints.clone()),
        ];
        for (what, names) in lists {
            if !names.is_empty() {
                lines.push(format!("{what}: {}", names.join(", ")));
            }
        }
        lines
    }

    /// The frozen joints' names.
    pub fn frozen_joint_names(&self) -> Vec<String> {
        self.frozen_joints.iter().map(|(n, _)| n.clone()).collect()
    }
}

/// A floating joint's quaternion `[x, y, z, w]` of squared norm below this (`|quat| < 10⁻⁹`)
/// is refused (`DynamicsError::BadQuaternion`): it names no rotation. Others are normalised.
pub const MIN_QUATERNION_NORM_SQUARED: f64 = 1e-18;

/// Whether a floating joint's quaternion `[x, y, z, w]` can be normalised: its squared norm is
/// at least [`MIN_QUATERNION_NORM_SQUARED`] and finite (components beyond about 10¹⁵⁴
/// overflow it, and `σ = 2 / |quat|²` would be 0, the identity rotation whatever the
/// quaternion). A NaN component passes: it is refused as a non-finite coordinate.
#[inline(always)]
pub fn quaternion_is_usable(quat: &[f64]) -> bool {
    let norm2 = quat.iter().map(|x| x * x).sum::<f64>();
    !(norm2 < MIN_QUATERNION_NORM_SQUARED || norm2 == f64::INFINITY)
}

/// `|quat|` without overflow or underflow (scaled by the largest component), for messages.
pub fn quaternion_norm(quat: &[f64]) -> f64 {
    let largest = quat.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if largest == 0.0 || !largest.is_finite() {
        return largest;
    }
    largest
        * quat
            .iter()
            .map(|x| (x / largest).powi(2))
            .sum::<f64>()
            .sqrt()
}

/// The immutable robot model. Algorithms read it and write only into a
/// [`Workspace`](crate::Workspace).
#[derive(Clone, Debug)]
pub struct Model {
    /// Robot name from URDF.
    pub(crate) name: String,
    /// Bodies in topological order.
    pub(crate) bodies: Vec<Body>,
    /// Every URDF link, fused or not, in document order.
    pub(crate) links: Vec<LinkFrame>,
    /// Name of the root link (the world when the base is fixed).
    pub(crate) root_link: String,
    /// Links fused into a parent body through fixed joints (or into the root).
    pub(crate) fused_links: Vec<String>,
    /// Joints locked at a position (turned fixed), with that position.
    pub(crate) locked_joints: Vec<(String, f64)>,
    /// Joints that are fixed in the description.
    pub(crate) fixed_joints: Vec<String>,
    /// What the root/tip reduction and massless pruning removed.
    pub(crate) reduction: Reduction,
    /// Doubts about the description that did not stop it loading (each names the link), such as
    /// an inertia that breaks the triangle inequality, as some real robots' URDFs do.
    pub(crate) warnings: Vec<String>,
    /// Gravity acceleration in root (world) coordinates, m/s²; default (0, 0, −9.81).
    pub(crate) gravity: Vector3,
    /// Number of position coordinates.
    pub(crate) nq: usize,
    /// Number of velocity coordinates.
    pub(crate) nv: usize,
    /// For each velocity coordinate, the velocity coordinate of the nearest coordinate on the
    /// path to the root (Featherstone's `λ` over degrees of freedom), when the tree's sparsity
    /// holds; `None` when a mimic joint couples coordinates across branches.
    pub(crate) dof_parent: Option<Vec<Option<usize>>>,
    /// The model's identity: unique to each model built (or reduced) in this process, kept by a
    /// clone and by [`with_gravity`](Self::with_gravity) (nothing a
    /// [`Workspace`](crate::Workspace) holds depends on gravity). A workspace records it and
    /// refuses any other model.
    pub(crate) id: u64,
}

/// The identity of the next model built.
static NEXT_MODEL_ID: AtomicU64 = AtomicU64::new(1);

/// A model identity no model has had before in this process.
pub(crate) fn new_model_id() -> u64 {
    NEXT_MODEL_ID.fetch_add(1, Ordering::Relaxed)
}

/// One joint that carries coordinates, as listed by `model --json`.
#[derive(Clone, Debug, PartialEq)]
pub struct CoordinateJoint<'a> {
    pub name: &'a str,
    pub kind: &'a JointKind,
    pub q_index: usize,
    pub nq: usize,
    pub v_index: usize,
    pub nv: usize,
}

impl Model {
    /// Robot name from URDF.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Bodies in topological order (a parent before its children).
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Every URDF link, fused or not, in document order.
    pub fn links(&self) -> &[LinkFrame] {
        &self.links
    }

    /// Name of the root link (the world when the base is fixed).
    pub fn root_link(&self) -> &str {
        &self.root_link
    }

    /// Links fused into a parent body through fixed joints (or into the root).
    pub fn fused_links(&self) -> &[String] {
        &self.fused_links
    }

    /// Joints locked at a position (turned fixed), with that position.
    pub fn locked_joints(&self) -> &[(String, f64)] {
        &self.locked_joints
    }

    /// Joints that are fixed in the description.
    pub fn fixed_joints(&self) -> &[String] {
        &self.fixed_joints
    }

    /// What the root/tip reduction and massless pruning removed.
    pub fn reduction(&self) -> &Reduction {
        &self.reduction
    }

    /// Doubts about the description that did not stop it loading (each names the link).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Gravity acceleration in root (world) coordinates, m/s².
    pub fn gravity(&self) -> Vector3 {
        self.gravity
    }

    /// Number of position coordinates.
    pub fn nq(&self) -> usize {
        self.nq
    }

    /// Number of velocity coordinates.
    pub fn nv(&self) -> usize {
        self.nv
    }

    /// For each velocity coordinate, the velocity coordinate of the nearest coordinate on the
    /// path to the root (Featherstone's `λ` over degrees of freedom), when the tree's sparsity
    /// holds; `None` when a mimic joint couples coordinates across branches.
    pub fn dof_parent(&self) -> Option<&[Option<usize>]> {
        self.dof_parent.as_deref()
    }

    /// Number of bodies.
    pub fn nbodies(&self) -> usize {
        self.bodies.len()
    }

    /// True when some joint mimics another.
    pub fn has_mimic(&self) -> bool {
        self.bodies.iter().any(|b| b.joint.is_mimic())
    }

    /// The joints that own coordinates, in coordinate order.
    pub fn coordinate_joints(&self) -> impl Iterator<Item = CoordinateJoint<'_>> {
        self.bodies
            .iter()
            .filter(|b| !b.joint.is_mimic())
            .map(|b| CoordinateJoint {
                name: &b.joint.name,
                kind: &b.joint.kind,
                q_index: b.joint.coords.q_index,
                nq: b.joint.kind.nq(),
                v_index: b.joint.coords.v_index,
                nv: b.joint.kind.nv(),
            })
    }

    /// The joint owning position coordinate `index` (with the offset inside the joint).
    pub fn joint_of_q(&self, index: usize) -> Option<(&str, usize)> {
        self.coordinate_joints()
            .find(|j| (j.q_index..j.q_index + j.nq).contains(&index))
            .map(|j| (j.name, index - j.q_index))
    }

    /// The joint owning velocity coordinate `index` (with the offset inside the joint).
    pub fn joint_of_v(&self, index: usize) -> Option<(&str, usize)> {
        self.coordinate_joints()
            .find(|j| (j.v_index..j.v_index + j.nv).contains(&index))
            .map(|j| (j.name, index - j.v_index))
    }

    /// Human-readable name of velocity coordinate `index`: the joint name, with the component
    /// for multi-dof joints (`base[2]`).
    pub fn v_name(&self, index: usize) -> String {
        match self.joint_of_v(index) {
            Some((name, 0)) if self.v_dof_count(name) == 1 => name.to_string(),
            Some((name, k)) => format!("{name}[{k}]"),
            None => format!("v[{index}]"),
        }
    }

    fn v_dof_count(&self, name: &str) -> usize {
        self.coordinate_joints()
            .find(|j| j.name == name)
            .map_or(0, |j| j.nv)
    }

    /// The [`LinkFrame`] of URDF link `name`: the body carrying it (the body made from it, the
    /// one it is fused, locked or lumped into, or `None` when it is fixed to the world) and
    /// `x_body_link`, the transform from that body's frame to the link's. `None` when the model
    /// has no such link (not in the description, or below a pruned massless joint).
    pub fn link(&self, name: &str) -> Option<&LinkFrame> {
        self.links.iter().find(|l| l.name == name)
    }

    /// `q ⊕ v·dt` for the whole model (each joint on its own manifold), into `out`. `q` and
    /// `out` must have `nq` values and `v` `nv`: else [`DynamicsError::Length`] names the
    /// vector, and `out` is untouched.
    pub fn integrate(
        &self,
        q: &[f64],
        v: &[f64],
        dt: f64,
        out: &mut [f64],
    ) -> Result<(), DynamicsError> {
        check_len("q", self.nq, q.len())?;
        check_len("v", self.nv, v.len())?;
        check_len("out", self.nq, out.len())?;
        for j in self.coordinate_joints() {
            let (qs, vs) = (j.q_index..j.q_index + j.nq, j.v_index..j.v_index + j.nv);
            j.kind.integrate(&q[qs.clone()], &v[vs], dt, &mut out[qs]);
        }
        Ok(())
    }

    /// The neutral configuration: every joint at [`JointKind::neutral`].
    pub fn neutral(&self) -> Vec<f64> {
        let mut q = vec![0.0; self.nq];
        for j in self.coordinate_joints() {
            j.kind.neutral(&mut q[j.q_index..j.q_index + j.nq]);
        }
        q
    }

    /// The model with a different gravity vector.
    pub fn with_gravity(mut self, gravity: Vector3) -> Result<Self, ModelError> {
        if !gravity.iter().all(|g| g.is_finite()) {
            return Err(ModelError::Invalid(format!(
                "gravity must be finite, got ({}, {}, {})",
                gravity.x, gravity.y, gravity.z
            )));
        }
        self.gravity = gravity;
        Ok(self)
    }
}
