//! Model reduction: which joints of a description stay moving when only part of the robot matters
//! ([`ModelOptions::root`], [`ModelOptions::tips`]) and which massless subtrees are pruned
//! ([`ModelOptions::prune_massless`]). The builder then freezes, fuses and drops accordingly.
//!
//! Why each reduction is exact for the coordinates kept:
//! - A joint outside the kept part is *frozen* at a position `q₀` (its `--lock` value, else the
//!   neutral one) with `q̇ = q̈ = 0`. Its child then moves rigidly with its parent, so fusing the
//!   child into the parent body (inertia transformed by `X_J(q₀) X_tree` and added) leaves the
//!   kept equations of motion unchanged: the reduced model's `τ_k`, `H_kk` and `C_k` are the full
//!   model's with the frozen coordinates at `q₀`. Bodies past a tip become a payload lumped onto
//!   the tip; side branches lump onto the kept body they hang from.
//! - Links outside the root's subtree are fixed to the world: their inertia never enters the
//!   kept equations, and their frozen joints only place the root in the world (which fixes the
//!   direction of gravity in the root's frame).
//! - A moving joint whose whole subtree has zero spatial inertia carries nothing: every force in
//!   the subtree is zero, so its own `Sᵀ f = 0` and it adds nothing to its ancestors' forces.
//!   Removing it (and its coordinate) leaves every other coordinate's `τ`, `H` and `C` unchanged;
//!   it also removes the zero row and column that would make `H` singular.

use super::spec::{JointSpec, ModelOptions};
use super::JointKind;
use crate::error::ModelError;
use crate::spatial::Inertia;
use std::collections::HashMap;

/// The description's tree, by index: links and joints as the builder listed them.
pub(super) struct Topology<'a> {
    pub joints: &'a [JointSpec],
    /// Link names and inertias, by link index.
    pub link_names: Vec<&'a str>,
    pub inertias: Vec<&'a Inertia>,
    pub link_index: HashMap<&'a str, usize>,
    /// Joint indices by name.
    pub joint_index: HashMap<&'a str, usize>,
    /// Joints whose parent is each link, in document order.
    pub children: Vec<Vec<usize>>,
    /// The joint whose child is each link (`None` for the root).
    pub parent_joint: Vec<Option<usize>>,
    /// The description's root link.
    pub root: usize,
}

impl Topology<'_> {
    fn child(&self, j: usize) -> usize {
        self.link_index[self.joints[j].child.as_str()]
    }

    fn parent(&self, j: usize) -> usize {
        self.link_index[self.joints[j].parent.as_str()]
    }

    /// The joints below `link`, depth first, children in document order (an explicit stack: a
    /// chain of ten thousand links must not overflow the call stack).
    pub fn joints_below(&self, link: usize) -> Vec<usize> {
        let mut order = Vec::new();
        let mut stack: Vec<usize> = self.children[link].iter().rev().copied().collect();
        while let Some(j) = stack.pop() {
            order.push(j);
            stack.extend(self.children[self.child(j)].iter().rev());
        }
        order
    }

    fn link_named(&self, name: &str, option: &str) -> Result<usize, ModelError> {
        self.link_index.get(name).copied().ok_or_else(|| {
            ModelError::Invalid(format!("{option}: there is no link named '{name}'"))
        })
    }
}

/// What happens to each joint (indices into [`Topology::joints`]).
pub(super) struct Plan {
    /// Moving joints outside the kept part: frozen at their lock value or neutral position.
    pub frozen: Vec<bool>,
    /// Joints removed with their whole (massless) subtree: the first of each subtree and every
    /// joint below it.
    pub pruned: Vec<bool>,
}

impl Plan {
    /// Decides, for `options`, which joints stay moving, which freeze and which go.
    pub fn new(topo: &Topology, options: &ModelOptions) -> Result<Plan, ModelError> {
        let n = topo.joints.len();
        let invalid = |msg: String| Err(ModelError::Invalid(msg));
        let base = match &options.root {
            Some(name) => topo.link_named(name, "root")?,
            None => topo.root,
        };
        if options.floating_base && base != topo.root {
            return invalid(format!(
                "root '{}': with a floating base the root must be the description's root link '{}', where the floating joint attaches",
                topo.link_names[base], topo.link_names[topo.root]
            ));
        }
        let moving = |j: usize| topo.joints[j].kind.is_some();
        // Kept: every moving joint below the base, or only those on the paths base → tips.
        let mut kept = vec![false; n];
        let mut tip_links = vec![false; topo.inertias.len()];
        if options.tips.is_empty() {
            for j in topo.joints_below(base) {
                kept[j] = moving(j);
            }
        }
        for tip in &options.tips {
            let mut link = topo.link_named(tip, "tip")?;
            tip_links[link] = true;
            while link != base {
                let Some(j) = topo.parent_joint[link] else {
                    return invalid(format!(
                        "tip '{tip}' is not below the root '{}'",
                        topo.link_names[base]
                    ));
                };
                kept[j] = moving(j);
                link = topo.parent(j);
            }
        }
        let mut pruned = vec![false; n];
        if options.prune_massless {
            prune_massless(topo, base, &kept, &tip_links, options, &mut pruned);
        }
        let frozen = (0..n)
            .map(|j| moving(j) && !kept[j] && !pruned[j])
            .collect();
        let plan = Plan { frozen, pruned };
        check_locks(topo, options)?;
        plan.check_mimic(topo, options)?;
        Ok(plan)
    }

    /// A mimic follower cannot freeze while its leader keeps moving (the coupling would break);
    /// the converse is fine (the follower locks with its leader). A `--lock` on a follower is
    /// taken only when its leader is held too (locked, or frozen at its neutral position) at a
    /// position the lock agrees with: `q_follower = multiplier · q_leader + offset` within
    /// [`MIMIC_LOCK_TOLERANCE`] (relative beyond 1).
    fn check_mimic(&self, topo: &Topology, options: &ModelOptions) -> Result<(), ModelError> {
        if options.ignore_mimic {
            return Ok(());
        }
        let index = &topo.joint_index;
        let lock = |name: &str| {
            options
                .locked
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, v)| *v)
        };
        for (f, follower) in topo.joints.iter().enumerate() {
            let Some((leader, multiplier, offset)) = &follower.mimic else {
                continue;
            };
            let l = index.get(leader.as_str()).copied();
            let removed = self.pruned[f] || follower.kind.is_none();
            if let (Some(value), false) = (lock(&follower.name), removed) {
                let refuse = |why: String| {
                    Err(ModelError::Invalid(format!(
                        "cannot lock joint '{}' at {value:e}: it mimics '{leader}' ({} = {multiplier:e} · {leader} + {offset:e}), {why}",
                        follower.name, follower.name
                    )))
                };
                let held = match l {
                    None => return refuse("which does not exist".into()),
                    Some(l) => match &topo.joints[l].kind {
                        None => return refuse("which is not a moving joint".into()),
                        Some(kind) if kind.nq() != 1 => {
                            return refuse(
                                "which is not a revolute, continuous or prismatic joint".into(),
                            )
                        }
                        Some(kind) => lock(leader)
                            .or_else(|| self.frozen[l].then(|| neutral_position(kind)[0])),
                    },
                };
                let Some(q_leader) = held else {
                    return refuse(format!(
                        "which stays moving: lock '{leader}' instead (its followers lock with it)"
                    ));
                };
                let expected = multiplier * q_leader + offset;
                let agrees =
                    (value - expected).abs() <= MIMIC_LOCK_TOLERANCE * expected.abs().max(1.0);
                if !agrees {
                    return refuse(format!(
                        "held at {q_leader:e}, which puts '{}' at {expected:e}",
                        follower.name
                    ));
                }
            }
            let Some(l) = l else {
                continue;
            };
            let user_locked = lock(&topo.joints[l].name).is_some();
            let leader_moves = !self.frozen[l] && !self.pruned[l] && !user_locked;
            if self.frozen[f] && leader_moves {
                return Err(ModelError::Invalid(format!(
                    "joint '{}' mimics '{}', which stays moving, but lies outside the kept part of the tree: add a tip below it, or lock '{}'",
                    follower.name, topo.joints[l].name, topo.joints[l].name
                )));
            }
        }
        Ok(())
    }
}

/// Each joint is locked at most once, and a revolute or prismatic joint within its `<limit>`
/// range (when it has one: `lower < upper`; a missing `<limit>` gives none), as the joint could
/// stand there.
fn check_locks(topo: &Topology, options: &ModelOptions) -> Result<(), ModelError> {
    let mut seen = std::collections::HashSet::new();
    for (name, value) in &options.locked {
        if !seen.insert(name.as_str()) {
            return Err(ModelError::Invalid(format!(
                "joint '{name}' is locked twice: give one position for it"
            )));
        }
        let Some(joint) = topo
            .joint_index
            .get(name.as_str())
            .map(|&j| &topo.joints[j])
        else {
            continue;
        };
        let (lower, upper) = (joint.limits.lower, joint.limits.upper);
        let bounded = matches!(
            joint.kind,
            Some(JointKind::Revolute { .. } | JointKind::Prismatic { .. })
        ) && lower < upper;
        if bounded && !(lower..=upper).contains(value) {
            return Err(ModelError::Invalid(format!(
                "cannot lock joint '{name}' at {value:e}: outside its limits [{lower:e}, {upper:e}]"
            )));
        }
    }
    Ok(())
}

/// How far a `--lock` on a mimic follower may be from its leader's held position mapped through
/// the mimic (relative to the position when beyond 1): about what a position typed with seven
/// significant digits misses by.
const MIMIC_LOCK_TOLERANCE: f64 = 1e-6;

/// Marks, among the kept moving joints, those whose whole subtree has zero spatial inertia,
/// carries no tip and leads no mimic joint outside it (largest subtrees first). Linear in the
/// joints and mimic joints: each joint's subtree is an interval of the depth-first order, and a
/// subtree leads a follower outside it exactly when the followers of the leaders inside it do
/// not all fall in that interval (their first and last positions, summed up the tree, tell).
fn prune_massless(
    topo: &Topology,
    base: usize,
    kept: &[bool],
    tip_links: &[bool],
    options: &ModelOptions,
    pruned: &mut [bool],
) {
    let order = topo.joints_below(base);
    let n = topo.joints.len();
    // Joint j's subtree (j and every joint below its child) is order[pos[j]..pos[j] + size[j]].
    let mut pos = vec![usize::MAX; n];
    for (p, &j) in order.iter().enumerate() {
        pos[j] = p;
    }
    let mut size = vec![1usize; n];
    for &j in order.iter().rev() {
        if let Some(up) = topo.parent_joint[topo.parent(j)].filter(|&up| pos[up] != usize::MAX) {
            size[up] += size[j];
        }
    }
    // The first and last depth-first positions of the followers of the leaders in each subtree
    // (a follower outside the base's subtree counts as before everything).
    let mut followers: Vec<Option<(isize, isize)>> = vec![None; n];
    if !options.ignore_mimic {
        for (f, joint) in topo.joints.iter().enumerate() {
            let Some(l) = joint
                .mimic
                .as_ref()
                .and_then(|(leader, _, _)| topo.joint_index.get(leader.as_str()).copied())
            else {
                continue;
            };
            let at = if pos[f] == usize::MAX {
                -1
            } else {
                pos[f] as isize
            };
            followers[l] = Some(followers[l].map_or((at, at), |(lo, hi)| (lo.min(at), hi.max(at))));
        }
    }
    let mut empty: Vec<bool> = (0..topo.inertias.len())
        .map(|l| is_zero(topo.inertias[l]) && !tip_links[l])
        .collect();
    // Bottom-up (reverse depth-first order): a link's subtree is massless and tip-free when the
    // link is and every child subtree is; followers gather the same way.
    for &j in order.iter().rev() {
        if !empty[topo.child(j)] {
            empty[topo.parent(j)] = false;
        }
        if let (Some(up), Some((lo, hi))) = (topo.parent_joint[topo.parent(j)], followers[j]) {
            if pos[up] != usize::MAX {
                followers[up] =
                    Some(followers[up].map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
            }
        }
    }
    let leads_outside = |j: usize| {
        followers[j].is_some_and(|(lo, hi)| {
            let (start, end) = (pos[j] as isize, (pos[j] + size[j]) as isize);
            lo < start || hi >= end
        })
    };
    let mut removed = vec![false; n];
    for &j in &order {
        if removed[j] || !kept[j] || !empty[topo.child(j)] || leads_outside(j) {
            continue;
        }
        for &k in &order[pos[j]..pos[j] + size[j]] {
            removed[k] = true;
            pruned[k] = true;
        }
    }
}

/// Zero mass, first moment and rotational inertia: a link that weighs nothing and spins freely.
fn is_zero(i: &Inertia) -> bool {
    i.mass == 0.0 && i.h.iter().chain(i.i_bar.iter()).all(|x| *x == 0.0)
}

/// The position a frozen joint of `kind` takes when no `--lock` gives one.
pub(super) fn neutral_position(kind: &JointKind) -> Vec<f64> {
    let mut q = vec![0.0; kind.nq()];
    kind.neutral(&mut q);
    q
}
