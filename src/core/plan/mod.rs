//! The choices the algorithms make once per model and then follow on every call: which form
//! each joint's transform takes, where ABA's aligned frames are anchored, which coordinates CRBA
//! works in and how it mirrors `H`, the coordinate tree's ancestor lists for the sparse
//! factorisation, each body's support for the frame algorithms, and the instruction set the hot
//! passes run in. Built from the model alone ([`Plan::new`]), the instruction set from the
//! processor; every [`Workspace`](crate::Workspace) holds its model's plan beside its scratch
//! buffers.

use crate::model::{Joint, JointKind, Model, UpShape};
use crate::InstructionSet;

pub mod flop_table;
pub mod flops;

/// What the algorithms decide once for a model. Fixed for the model's lifetime, but for the
/// instruction set, detected from the processor and open to a caller's choice
/// ([`Workspace::set_instruction_set`](crate::Workspace::set_instruction_set)).
#[derive(Clone, Debug)]
pub struct Plan {
    /// `Some((k, σ))` for a revolute joint about a coordinate axis `σ e_k`
    /// (`JointKind::turn_axis`): its angle goes straight into a turn about that axis.
    pub turn_axes: Vec<Option<(usize, f64)>>,
    /// For each body, the columns of `S_i` that are a signed unit vector of `[ω; v]` whatever
    /// `q` ([`JointKind::subspace_axes`]).
    pub s_axes: Vec<[Option<(usize, f64)>; 6]>,
    /// For each body, the form of `ⁱX_λ` whatever `q` ([`JointKind::up_shape`]).
    pub up_shapes: Vec<UpShape>,
    /// True when no joint is a mimic follower: each velocity coordinate is then one joint's, and
    /// a Jacobian's column is written by that joint's body alone (assigned, not summed).
    pub own_columns: bool,
    /// Which bodies anchor an aligned frame in ABA's passes ([`frame_anchors`]): every root, and
    /// bodies far along the tree from the anchor above them.
    pub anchors: Vec<bool>,
    /// The coordinates CRBA's row blocks work in ([`crba_frames`]).
    pub crba_frames: CrbaFrames,
    /// For each velocity coordinate, one past the last coordinate of its body's subtree, when
    /// every subtree's coordinates are contiguous (bodies depth-first, coordinates in body order,
    /// no mimic joints): body `i`'s subtree then owns `v_index_i .. subtree_end[v_index_i]`, and
    /// row `k` of `H` is zero beyond column `subtree_end[k]`. `None` otherwise
    /// ([`contiguous_subtrees`]).
    pub subtree_end: Option<Vec<usize>>,
    /// Whether CRBA leaves `H`'s upper triangle to be copied by tiles after its passes instead of
    /// storing each entry's mirror beside it (`mirror_by_tiles`).
    pub mirror_by_tiles: bool,
    /// The ancestors of each coordinate and the range of its subtree, for the sparse
    /// factorisation; `None` when mimic joints break the tree pattern
    /// ([`Model::dof_parent`]) or the coordinates are not numbered depth-first (then the dense
    /// Cholesky factorises `H`).
    pub dof_ancestors: Option<Ancestors>,
    /// The bodies supporting each body, for the frame algorithms ([`Supports`]).
    pub supports: Supports,
    /// The bodies from the first to the last whose joint turns about a coordinate axis
    /// (`turn_axes`): the turn angles whose sines and cosines a pass over the tree needs (the
    /// other joints ignore theirs).
    pub turning: std::ops::Range<usize>,
    /// The instruction set the dispatched passes run in ([`InstructionSet::best`] unless set).
    pub instruction_set: InstructionSet,
}

impl Plan {
    /// The plan for `model`.
    pub fn new(model: &Model) -> Plan {
        let subtree_end = contiguous_subtrees(model);
        Plan {
            turn_axes: model
                .bodies
                .iter()
                .map(|b| b.joint.kind.turn_axis())
                .collect(),
            s_axes: model
                .bodies
                .iter()
                .map(|b| b.joint.kind.subspace_axes())
                .collect(),
            up_shapes: model
                .bodies
                .iter()
                .map(|b| b.joint.kind.up_shape(&b.x_tree))
                .collect(),
            own_columns: model.bodies.iter().all(|b| !b.joint.is_mimic()),
            anchors: frame_anchors(model),
            crba_frames: crba_frames(model, subtree_end.as_deref()),
            mirror_by_tiles: mirror_by_tiles(model.nv),
            subtree_end,
            dof_ancestors: model.dof_parent.as_deref().and_then(Ancestors::new),
            supports: Supports::new(model),
            turning: turning_bodies(model),
            instruction_set: InstructionSet::best(),
        }
    }
}

/// The coordinates the row-block inward pass works in (Pinocchio's `Convention`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrbaFrames {
    /// World (root) coordinates: each body's inertia and axes are carried to the world once,
    /// and an entry of `H` is one product `⁰S_jᵀ F_c` (the first scheme of `algorithms::crba`).
    World,
    /// Each body's own coordinates: no placements, and a joint axis that is a coordinate axis
    /// reads one component of `F`, but each column force is moved up one body at a time (the second
    /// scheme of `algorithms::crba`).
    Local,
}

/// The frames with fewer operations for `model` by the counts of [`flops::crba_world`] and
/// [`flops::crba_local`]: body coordinates for short branches (arms, legs, a floating root over
/// them), world coordinates for long ones; world coordinates when mimic joints break the tree
/// pattern (only the world pass handles them); body coordinates when a slide below a root can
/// carry its bodies farther than the aligned frames' anchor spacing (`travels_far`:
/// world rows keep one frame per tree).
pub fn crba_frames(model: &Model, subtree_end: Option<&[usize]>) -> CrbaFrames {
    if model.dof_parent.is_none() {
        return CrbaFrames::World;
    }
    if travels_far(model) {
        // World rows keep one frame per tree: a body a long slide carries far from its root
        // would bring `m d²` terms that cancel. Body coordinates have no such distance.
        return CrbaFrames::Local;
    }
    let (world, local) = (
        flops::crba_world(model, subtree_end.is_none()),
        flops::crba_local(model),
    );
    if local.total() < world.total() {
        CrbaFrames::Local
    } else {
        CrbaFrames::World
    }
}

/// Whether CRBA's `mirror_lower` copies `H`'s upper triangle by tiles (else each entry's mirror is
/// stored beside it): when a row's mirror stores, `8n` bytes apart, would outnumber the lines the
/// L1 cache sets they reach can hold. An L1 way spans 4 KiB (64 sets of 64-byte lines) on
/// current x86 cores; eight ways are counted (AMD's; Intel's hold twelve, so 160 and 224 tile
/// where they need not there). True for 128, 160, 192, 224, every multiple of 16 from 256 to
/// 512, and every `n` beyond 512 (a row then exceeds 64 sets of eight lines).
pub(crate) fn mirror_by_tiles(n: usize) -> bool {
    const WAY_BYTES: usize = 4096;
    const LINE_BYTES: usize = 64;
    const WAYS: usize = 8;
    let stride = 8 * n;
    let mut gcd = (WAY_BYTES, stride);
    while gcd.1 != 0 {
        gcd = (gcd.1, gcd.0 % gcd.1);
    }
    let sets = WAY_BYTES / gcd.0.max(LINE_BYTES);
    n > WAYS * sets
}

/// Distance along the tree (sum of joint-origin offsets `|r_tree|` and of prismatic joints'
/// travel) after which a body starts a new aligned frame, in multiples `s` of the model's
/// longest offset `ℓ`: a body's origin is at most `(s + 1) ℓ` from its frame's (a slide that
/// can travel farther starts a frame at its body), so its inertia carries
/// terms up to about `(s + 1)² = 25` times those about its own origin. On chains of 256 equal
/// links the relative error of ABA's `q̈` is 3.7e-15 at `s = 1`, 1.0e-14 at 2, 3.8e-14
/// at 4, 7.1e-14 at 8, 1.8e-12 without interior anchors; at 4 none of the benchmark robots
/// (UR5 … TALOS) needs one, so they pay nothing for it.
pub(crate) const ANCHOR_SPACING: f64 = 4.0;

/// Which bodies anchor an aligned frame with spaced anchors: every root and each body
/// whose joint origin can be more than `ANCHOR_SPACING` longest offsets along the tree from
/// the anchor above it, counting each prismatic joint's travel (its largest `|limit|`; a
/// planar or floating joint below the root travels without bound).
pub fn frame_anchors(model: &Model) -> Vec<bool> {
    let spacing = anchor_spacing(model);
    let mut along = vec![0.0; model.nbodies()];
    let mut anchors = vec![true; model.nbodies()];
    for (i, body) in model.bodies.iter().enumerate() {
        if let Some(p) = body.parent {
            along[i] = along[p] + body.x_tree.trans.norm() + travel(&body.joint);
            anchors[i] = along[i] > spacing;
            if anchors[i] {
                along[i] = 0.0;
            }
        }
    }
    anchors
}

/// [`ANCHOR_SPACING`] times the model's longest joint offset `|r_tree|`.
fn anchor_spacing(model: &Model) -> f64 {
    let longest = model
        .bodies
        .iter()
        .map(|b| b.x_tree.trans.norm())
        .fold(0.0, f64::max);
    ANCHOR_SPACING * longest
}

/// True when a joint below a root can travel farther than the anchor spacing (a long rail):
/// a pass with one frame per tree (anchors at the roots only) would then hold inertias far from their
/// bodies and lose digits in proportion to the travel squared.
pub(crate) fn travels_far(model: &Model) -> bool {
    let spacing = anchor_spacing(model);
    model
        .bodies
        .iter()
        .any(|b| b.parent.is_some() && travel(&b.joint) > spacing)
}

/// How far `joint` moves its body's origin from the joint origin within its limits: a slide's
/// largest `|limit|` (unbounded without limits), without bound for a planar or floating joint,
/// 0 for a turn. (A slide driven past its limits is not refused: its body's frame is then
/// farther from its anchor, and digits go as described at [`ANCHOR_SPACING`].)
fn travel(joint: &Joint) -> f64 {
    match joint.kind {
        JointKind::Prismatic { .. } => joint.limits.lower.abs().max(joint.limits.upper.abs()),
        JointKind::Planar { .. } | JointKind::Floating => f64::INFINITY,
        JointKind::Revolute { .. } | JointKind::Continuous { .. } => 0.0,
    }
}

/// [`Plan::subtree_end`] when each subtree's coordinates are contiguous.
pub fn contiguous_subtrees(model: &Model) -> Option<Vec<usize>> {
    model.dof_parent.as_ref()?;
    let n = model.nbodies();
    let mut end = vec![0; n];
    let mut count = vec![0; n];
    let mut next_v = 0;
    for (i, body) in model.bodies.iter().enumerate() {
        let c = body.joint.coords;
        if c.v_index != next_v || c.scale != 1.0 {
            return None;
        }
        next_v += body.joint.kind.nv();
        end[i] = next_v;
        count[i] = body.joint.kind.nv();
    }
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let c = body.joint.coords;
        if count[i] != end[i] - c.v_index {
            return None;
        }
        if let Some(p) = body.parent {
            end[p] = end[p].max(end[i]);
            count[p] += count[i];
        }
    }
    let mut dof_end = vec![0; model.nv];
    for (body, e) in model.bodies.iter().zip(end) {
        let c = body.joint.coords;
        dof_end[c.v_index..c.v_index + body.joint.kind.nv()].fill(e);
    }
    Some(dof_end)
}

/// The proper ancestors of every degree of freedom, nearest first (`λ(k), λ(λ(k)), …`), and the
/// end of each one's subtree, listed once per model so that the factorisation and the solves
/// walk plain slices.
#[derive(Clone, Debug)]
pub struct Ancestors {
    list: Vec<usize>,
    start: Vec<usize>,
    end: Vec<usize>,
}

impl Ancestors {
    /// From `λ` over degrees of freedom ([`Model::dof_parent`](crate::Model)), when every
    /// subtree is a contiguous range `k + 1 .. e(k)` (depth-first numbering, as the model builder
    /// makes it); `None` otherwise.
    pub fn new(lambda: &[Option<usize>]) -> Option<Self> {
        let n = lambda.len();
        if (0..n).any(|k| lambda[k].is_some_and(|p| p >= k)) {
            return None;
        }
        // Sized once (a chain's list holds n(n − 1)/2 entries: no doubling past it).
        let mut depth = vec![0usize; n];
        for k in 0..n {
            depth[k] = lambda[k].map_or(0, |p| depth[p] + 1);
        }
        let mut list = Vec::with_capacity(depth.iter().sum());
        let mut start = Vec::with_capacity(n + 1);
        start.push(0);
        for k in 0..n {
            list.extend(std::iter::successors(lambda[k], |&i| lambda[i]));
            start.push(list.len());
        }
        // e(k) and the subtree's size; contiguous when they agree and parents come first.
        let mut end: Vec<usize> = (1..=n).collect();
        let mut size = vec![1; n];
        for k in (0..n).rev() {
            if let Some(p) = lambda[k] {
                end[p] = end[p].max(end[k]);
                size[p] += size[k];
            }
        }
        (0..n)
            .all(|k| end[k] - k == size[k])
            .then_some(Ancestors { list, start, end })
    }

    /// The ancestors of `k`, nearest first; those of `of(k)[m]` are `of(k)[m + 1..]`.
    pub fn of(&self, k: usize) -> &[usize] {
        &self.list[self.start[k]..self.start[k + 1]]
    }

    /// The descendants of `k`: `k + 1 .. e(k)`.
    pub fn below(&self, k: usize) -> std::ops::Range<usize> {
        k + 1..self.end[k]
    }

    /// The number of degrees of freedom.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// The entries of all the lists (for the workspace's footprint).
    #[cfg(test)]
    pub(crate) fn entries(&self) -> usize {
        self.list.len()
    }
}

/// The range from the first to the last body whose joint turns about a coordinate axis (empty
/// when none does).
fn turning_bodies(model: &Model) -> std::ops::Range<usize> {
    let turns = |i: &usize| model.bodies[*i].joint.kind.turn_axis().is_some();
    let n = model.nbodies();
    match ((0..n).find(turns), (0..n).rev().find(turns)) {
        (Some(first), Some(last)) => first..last + 1,
        _ => 0..0,
    }
}

/// The *support* of each body: the bodies from its root down to it, root first (each one's
/// parent just before it), the bodies that move a frame it carries. Listed once per model, so
/// that a frame algorithm walks a slice instead of chasing parents.
#[derive(Clone, Debug)]
pub struct Supports {
    list: Vec<usize>,
    start: Vec<usize>,
    turns_and_slides: Vec<bool>,
}

impl Supports {
    /// From the model's tree (every parent before its children).
    pub fn new(model: &Model) -> Self {
        // Sized once (a chain's list holds n(n + 1)/2 entries: no doubling past it).
        let mut depth = vec![0usize; model.nbodies()];
        for (i, body) in model.bodies.iter().enumerate() {
            depth[i] = body.parent.map_or(1, |p| depth[p] + 1);
        }
        let mut list = Vec::with_capacity(depth.iter().sum());
        let mut start = Vec::with_capacity(model.nbodies() + 1);
        start.push(0);
        let mut turns_and_slides: Vec<bool> = Vec::with_capacity(model.nbodies());
        for (i, body) in model.bodies.iter().enumerate() {
            let kind = body.joint.kind;
            let turn_or_slide = match kind {
                JointKind::Floating => body.parent.is_none(),
                JointKind::Prismatic { .. } => true,
                _ => kind.turn_axis().is_some(),
            };
            let own = turn_or_slide && !body.joint.is_mimic();
            let above = body.parent.is_none_or(|p| turns_and_slides[p]);
            turns_and_slides.push(own && above);
            if let Some(p) = body.parent {
                list.extend_from_within(start[p]..start[p + 1]);
            }
            list.push(i);
            start.push(list.len());
        }
        Supports {
            list,
            start,
            turns_and_slides,
        }
    }

    /// The entries of all the supports (for the workspace's footprint).
    #[cfg(test)]
    pub(crate) fn entries(&self) -> usize {
        self.list.len()
    }

    /// The support of body `i`, root first, ending with `i`.
    pub fn of(&self, i: usize) -> &[usize] {
        &self.list[self.start[i]..self.start[i + 1]]
    }

    /// Whether every joint of body `i`'s support turns about a coordinate axis or slides (none
    /// a mimic follower), but for a floating root.
    pub fn turns_and_slides(&self, i: usize) -> bool {
        self.turns_and_slides[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::{self, pendulum_urdf};
    use crate::{urdf, ModelOptions};

    fn load(text: &str, floating_base: bool) -> Model {
        let options = ModelOptions {
            floating_base,
            ..ModelOptions::default()
        };
        urdf::model_from_str(text, &options).unwrap()
    }

    /// Each body's support is the path from its root down to it, as its parents give it: on a
    /// branching tree and on an arm over a floating base.
    #[test]
    fn supports_are_the_paths_from_the_roots() {
        for model in [
            load(include_str!("../tests/models/tree.urdf"), false),
            load(examples::DEFAULT_ARM_URDF, true),
        ] {
            let supports = Supports::new(&model);
            for i in 0..model.nbodies() {
                let mut path: Vec<usize> =
                    std::iter::successors(Some(i), |&b| model.bodies[b].parent).collect();
                path.reverse();
                assert_eq!(supports.of(i), &path[..], "{}: body {i}", model.name);
            }
        }
    }

    /// A support is of turns and slides down to the first joint that neither slides nor turns
    /// about a coordinate axis (a revolute about (0.6, 0.8, 0), a planar root) or is a mimic
    /// follower; a floating root may start one.
    #[test]
    fn supports_are_of_turns_and_slides_down_to_the_first_other_joint() {
        let cases = [
            (include_str!("../tests/models/quarter_turns.urdf"), true),
            (include_str!("../tests/models/tree.urdf"), false),
            (examples::MIMIC_GRIPPER_URDF, false),
        ];
        for (text, floating_base) in cases {
            let model = load(text, floating_base);
            let supports = Supports::new(&model);
            for (i, body) in model.bodies.iter().enumerate() {
                let other = |b: usize| {
                    let joint = &model.bodies[b].joint;
                    let planar = matches!(joint.kind, JointKind::Planar { .. });
                    joint.name == "j8" || joint.is_mimic() || planar
                };
                let mut path = std::iter::successors(Some(i), |&b| model.bodies[b].parent);
                let want = !path.any(other);
                let name = &body.joint.name;
                assert_eq!(supports.turns_and_slides(i), want, "{}: {name}", model.name);
            }
        }
    }

    /// The turning bodies' range spans the arm's revolute joints and leaves out a floating
    /// base before them.
    #[test]
    fn turning_bodies_span_the_turning_joints() {
        let fixed = load(examples::DEFAULT_ARM_URDF, false);
        assert_eq!(turning_bodies(&fixed), 0..fixed.nbodies());
        let floating = load(examples::DEFAULT_ARM_URDF, true);
        assert_eq!(turning_bodies(&floating), 1..floating.nbodies());
    }

    /// The mirror is copied by tiles where a row's stores, `8n` bytes apart, fall in too few L1
    /// sets: the sizes where the mirror beside each entry is 2–3× slower (chains of 128, 192
    /// and 256 links) and every size beyond 512; not below 128, nor the sizes where the mirror
    /// beside each entry is the faster (112, 120, 136, 200, 300).
    #[test]
    fn mirror_by_tiles_where_strides_conflict() {
        for n in [128, 192, 256].into_iter().chain(513..600) {
            assert!(mirror_by_tiles(n), "{n}");
        }
        for n in (0..128).chain([136, 200, 300]) {
            assert!(!mirror_by_tiles(n), "{n}");
        }
    }

    /// Short branches count fewer operations in body coordinates, a long chain fewer in world
    /// coordinates (one product an entry instead of moving each column force up a body).
    #[test]
    fn frames_follow_the_operation_counts() {
        assert_eq!(
            Plan::new(&load(examples::DEFAULT_ARM_URDF, true)).crba_frames,
            CrbaFrames::Local
        );
        assert_eq!(
            Plan::new(&load(&pendulum_urdf(60, 0.5, 0.7), false)).crba_frames,
            CrbaFrames::World
        );
    }
}
