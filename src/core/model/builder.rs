//! Building a [`Model`] from links and joints, whatever file format they came from: the tree is
//! ordered, fixed joints are fused, mimic joints are resolved and coordinates are numbered.

use super::orientation::orient_bodies;
use super::reduction::{neutral_position, Plan, Topology};
use super::spec::{BodySpec, JointSpec, ModelOptions};
use super::{
    Body, CoordinateMap, Joint, JointKind, JointLimits, LinkFrame, Mimic, Model, MotionSubspace,
    Reduction,
};
use crate::error::ModelError;
use crate::spatial::Transform;
use crate::Workspace;
use std::collections::{HashMap, HashSet};

/// Collects links and joints, then builds the model.
#[derive(Clone, Debug, Default)]
pub struct ModelBuilder {
    name: String,
    links: Vec<BodySpec>,
    joints: Vec<JointSpec>,
}

/// Name of the joint added by [`ModelOptions::floating_base`] (Pinocchio's name for it).
pub const FLOATING_BASE_JOINT: &str = "root_joint";

impl ModelBuilder {
    /// An empty robot called `name`.
    pub fn new(name: &str) -> Self {
        ModelBuilder {
            name: name.to_string(),
            ..Default::default()
        }
    }

    /// Adds a link.
    pub fn link(&mut self, link: BodySpec) -> &mut Self {
        self.links.push(link);
        self
    }

    /// Adds a joint.
    pub fn joint(&mut self, joint: JointSpec) -> &mut Self {
        self.joints.push(joint);
        self
    }

    /// Checks the tree and builds the model, with body frames turned so that quarter-turn joint
    /// placements lose their rotation (see [`Body::name`](super::Body::name)).
    pub fn build(&self, options: &ModelOptions) -> Result<Model, ModelError> {
        let mut model = self.build_in_link_frames(options)?;
        orient_bodies(&mut model);
        check_footprint(&model)?;
        Ok(model)
    }

    /// The model with each body's frame its link's frame (before [`orient_bodies`]).
    pub(crate) fn build_in_link_frames(&self, options: &ModelOptions) -> Result<Model, ModelError> {
        let topo = self.topology()?;
        let plan = Plan::new(&topo, options)?;
        let root_link = &self.links[topo.root];
        check_inertia(root_link)?;
        let mut state = TreeState::new(&self.name, root_link, options);
        state.model.reduction.root = options.root.clone();
        state.model.reduction.tips = options.tips.clone();
        let mut stack: Vec<usize> = topo.children[topo.root].iter().rev().copied().collect();
        while let Some(j) = stack.pop() {
            let joint = &self.joints[j];
            let child = topo.link_index[joint.child.as_str()];
            if plan.pruned[j] {
                // The first joint of a massless subtree: drop it and everything below it.
                let below = topo.joints_below(child);
                let reduction = &mut state.model.reduction;
                reduction.pruned_joints.push(joint.name.clone());
                reduction.pruned_links.push(joint.child.clone());
                for k in below {
                    reduction.pruned_joints.push(self.joints[k].name.clone());
                    reduction.pruned_links.push(self.joints[k].child.clone());
                }
                continue;
            }
            let lock = self.lock_position(j, &topo, &plan, options);
            state.attach(joint, &self.links[child], lock, options)?;
            stack.extend(topo.children[child].iter().rev());
        }
        if let Some((name, _)) = options.locked.iter().find(|(name, _)| {
            !state.model.locked_joints.iter().any(|(l, _)| l == name)
                && !state.model.reduction.pruned_joints.contains(name)
        }) {
            return Err(ModelError::Invalid(format!(
                "cannot lock joint '{name}': there is no moving joint of that name"
            )));
        }
        if state.model.links.len() + state.model.reduction.pruned_links.len() != self.links.len() {
            let reached: HashSet<&str> = state
                .model
                .links
                .iter()
                .map(|l| l.name.as_str())
                .chain(
                    state
                        .model
                        .reduction
                        .pruned_links
                        .iter()
                        .map(|l| l.as_str()),
                )
                .collect();
            let lost: Vec<&str> = self
                .links
                .iter()
                .map(|l| l.name.as_str())
                .filter(|l| !reached.contains(l))
                .collect();
            return Err(ModelError::Invalid(format!(
                "links {} are not connected to the root '{}': their joints form a cycle",
                lost.join(", "),
                root_link.name
            )));
        }
        state.number_coordinates()?;
        let model = state.model;
        model.with_gravity(options.gravity)
    }

    /// Indexes the links and joints and checks that they form one tree.
    fn topology(&self) -> Result<Topology<'_>, ModelError> {
        let invalid = |msg: String| Err(ModelError::Invalid(msg));
        let link_index = self.index_links()?;
        let mut joint_names = HashSet::new();
        let mut parent_joint: Vec<Option<usize>> = vec![None; self.links.len()];
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); self.links.len()];
        for (j, joint) in self.joints.iter().enumerate() {
            if !joint_names.insert(joint.name.as_str()) {
                return invalid(format!("joint '{}' is defined twice", joint.name));
            }
            for (role, link) in [("parent", &joint.parent), ("child", &joint.child)] {
                if !link_index.contains_key(link.as_str()) {
                    return invalid(format!(
                        "joint '{}': its {role} link '{link}' does not exist",
                        joint.name
                    ));
                }
            }
            let child = link_index[joint.child.as_str()];
            if let Some(other) = parent_joint[child] {
                return invalid(format!(
                    "link '{}' is the child of two joints, '{}' and '{}'",
                    joint.child, self.joints[other].name, joint.name
                ));
            }
            parent_joint[child] = Some(j);
            children[link_index[joint.parent.as_str()]].push(j);
        }
        if self.links.is_empty() {
            return invalid(format!(
                "robot '{}' has no links: a URDF needs at least one <link> element (directly inside <robot>)",
                self.name
            ));
        }
        let roots: Vec<usize> = (0..self.links.len())
            .filter(|&l| parent_joint[l].is_none())
            .collect();
        let root = match roots.as_slice() {
            [root] => *root,
            [] => {
                return invalid(
                    "no root link: every link is some joint's child, so the joints form a cycle"
                        .into(),
                )
            }
            many => {
                let names: Vec<&str> = many.iter().map(|&l| self.links[l].name.as_str()).collect();
                return invalid(format!(
                    "several root links ({}): a URDF must describe one tree",
                    names.join(", ")
                ));
            }
        };
        Ok(Topology {
            joints: &self.joints,
            link_names: self.links.iter().map(|l| l.name.as_str()).collect(),
            inertias: self.links.iter().map(|l| &l.inertia).collect(),
            link_index,
            joint_index: self
                .joints
                .iter()
                .enumerate()
                .map(|(j, joint)| (joint.name.as_str(), j))
                .collect(),
            children,
            parent_joint,
            root,
        })
    }

    /// The position joint `j` is held at, if it does not move: its `--lock` value (for a mimic
    /// follower, [`Plan::new`] has checked that it agrees with its leader's), its mimic leader's
    /// held position mapped through it, or the neutral position if the reduction freezes it.
    /// The flag tells whether the user asked for it (a lock) or the reduction did (a freeze).
    fn lock_position(
        &self,
        j: usize,
        topo: &Topology,
        plan: &Plan,
        options: &ModelOptions,
    ) -> Option<(Vec<f64>, bool)> {
        let joint = &self.joints[j];
        let locked = |k: usize| {
            let name = &self.joints[k].name;
            options
                .locked
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, v)| (vec![*v], true))
        };
        let frozen = |k: usize| {
            let kind = self.joints[k].kind.as_ref()?;
            plan.frozen[k].then(|| (neutral_position(kind), false))
        };
        let held = |k: usize| locked(k).or_else(|| frozen(k));
        let led = || match (&joint.mimic, options.ignore_mimic) {
            (Some((leader, multiplier, offset)), false) => {
                let l = *topo.joint_index.get(leader.as_str())?;
                held(l).map(|(q, by_user)| (vec![multiplier * q[0] + offset], by_user))
            }
            _ => None,
        };
        locked(j).or_else(led).or_else(|| frozen(j))
    }

    fn index_links(&self) -> Result<HashMap<&str, usize>, ModelError> {
        let mut index = HashMap::new();
        for (i, link) in self.links.iter().enumerate() {
            if index.insert(link.name.as_str(), i).is_some() {
                return Err(ModelError::Invalid(format!(
                    "link '{}' is defined twice",
                    link.name
                )));
            }
        }
        Ok(index)
    }
}

/// The model while it is being built, with the joints' mimic requests.
struct TreeState {
    model: Model,
    mimic: Vec<Option<(String, f64, f64)>>,
}

impl TreeState {
    fn new(name: &str, root_link: &BodySpec, options: &ModelOptions) -> Self {
        let root = root_link.name.as_str();
        let mut model = Model {
            name: name.to_string(),
            bodies: Vec::new(),
            links: Vec::new(),
            root_link: root.to_string(),
            fused_links: Vec::new(),
            locked_joints: Vec::new(),
            fixed_joints: Vec::new(),
            reduction: Reduction::default(),
            warnings: Vec::new(),
            gravity: options.gravity,
            nq: 0,
            nv: 0,
            dof_parent: None,
            id: super::new_model_id(),
        };
        let mut mimic = Vec::new();
        if options.floating_base {
            model.root_link = "world".to_string();
            model.bodies.push(Body {
                name: root.to_string(),
                parent: None,
                joint: Joint {
                    name: FLOATING_BASE_JOINT.to_string(),
                    kind: JointKind::Floating,
                    coords: CoordinateMap {
                        q_index: 0,
                        v_index: 0,
                        scale: 1.0,
                        offset: 0.0,
                    },
                    mimics: None,
                    limits: JointLimits::default(),
                },
                x_tree: Transform::identity(),
                inertia: root_link.inertia,
            });
            mimic.push(None);
        }
        model.links.push(LinkFrame {
            name: root.to_string(),
            body: options.floating_base.then_some(0),
            x_body_link: Transform::identity(),
        });
        TreeState { model, mimic }
    }

    /// Adds `link`, reached from its (already placed) parent through `joint`: a new body for a
    /// moving joint, a fusion into the parent's body for a fixed one.
    fn attach(
        &mut self,
        joint: &JointSpec,
        link: &BodySpec,
        lock: Option<(Vec<f64>, bool)>,
        options: &ModelOptions,
    ) -> Result<(), ModelError> {
        check_inertia(link)?;
        self.model.warnings.extend(inertia_doubts(link));
        let parent = self
            .model
            .link(&joint.parent)
            .expect("parents are placed before children")
            .clone();
        // Body frame → parent link frame → joint frame.
        let mut x_body_joint = joint.origin.compose(&parent.x_body_link);
        let mut kind = joint.kind;
        if let (Some(k), Some((position, by_user))) = (kind, lock) {
            if position.len() != k.nq() || !position.iter().all(|x| x.is_finite()) {
                return Err(ModelError::Invalid(format!("cannot lock joint '{}' at {position:?}: only revolute, continuous and prismatic joints lock, at a finite position", joint.name)));
            }
            // Frozen at q: the child frame sits at X_J(q) from the joint frame, for good.
            x_body_joint = k
                .jcalc(&position, &mut MotionSubspace::default())
                .compose(&x_body_joint);
            kind = None;
            let reduction = &mut self.model.reduction;
            if by_user {
                self.model
                    .locked_joints
                    .push((joint.name.clone(), position[0]));
            } else if parent.body.is_some() {
                reduction.frozen_joints.push((joint.name.clone(), position));
                reduction.payload_links.push(link.name.clone());
            } else {
                reduction.frozen_joints.push((joint.name.clone(), position));
                reduction.removed_links.push(link.name.clone());
            }
        }
        if !(x_body_joint.rot.iter().chain(x_body_joint.trans.iter())).all(|x| x.is_finite()) {
            return Err(ModelError::Invalid(format!(
                "link '{}': its placement in the body it belongs to is not finite (joint '{}' places it too far)",
                link.name, joint.name
            )));
        }
        match kind {
            None => {
                if let Some(body) = parent.body {
                    let fused = x_body_joint.transpose_apply_inertia(&link.inertia);
                    let inertia = &mut self.model.bodies[body].inertia;
                    *inertia += fused;
                    if !inertia_is_finite(inertia) {
                        return Err(ModelError::Invalid(format!(
                            "link '{}': fused through fixed joint '{}' into body '{}', it makes that body's inertia overflow (its mass {:e} kg at ({:e}, {:e}, {:e}) m)",
                            link.name,
                            joint.name,
                            self.model.bodies[body].name,
                            link.inertia.mass,
                            x_body_joint.trans.x,
                            x_body_joint.trans.y,
                            x_body_joint.trans.z
                        )));
                    }
                }
                self.model.fused_links.push(link.name.clone());
                if joint.kind.is_none() {
                    self.model.fixed_joints.push(joint.name.clone());
                }
                self.model.links.push(LinkFrame {
                    name: link.name.clone(),
                    body: parent.body,
                    x_body_link: x_body_joint,
                });
            }
            Some(kind) => {
                let body = self.model.bodies.len();
                self.model.bodies.push(Body {
                    name: link.name.clone(),
                    parent: parent.body,
                    joint: Joint {
                        name: joint.name.clone(),
                        kind,
                        coords: CoordinateMap {
                            q_index: 0,
                            v_index: 0,
                            scale: 1.0,
                            offset: 0.0,
                        },
                        mimics: None,
                        limits: joint.limits,
                    },
                    x_tree: x_body_joint,
                    inertia: link.inertia,
                });
                self.mimic.push(if options.ignore_mimic {
                    None
                } else {
                    joint.mimic.clone()
                });
                self.model.links.push(LinkFrame {
                    name: link.name.clone(),
                    body: Some(body),
                    x_body_link: Transform::identity(),
                });
            }
        }
        Ok(())
    }

    /// Numbers the coordinates in body order, then points each mimic joint at its leader's.
    fn number_coordinates(&mut self) -> Result<(), ModelError> {
        let (mut nq, mut nv) = (0, 0);
        for (body, mimic) in self.model.bodies.iter_mut().zip(&self.mimic) {
            if mimic.is_none() {
                body.joint.coords.q_index = nq;
                body.joint.coords.v_index = nv;
                nq += body.joint.kind.nq();
                nv += body.joint.kind.nv();
            }
        }
        self.model.nq = nq;
        self.model.nv = nv;
        // Each joint name's first body (a URDF joint may share the floating base's name).
        let mut body_of: HashMap<String, usize> = HashMap::new();
        for (b, body) in self.model.bodies.iter().enumerate() {
            body_of.entry(body.joint.name.clone()).or_insert(b);
        }
        for b in 0..self.model.bodies.len() {
            let Some((leader, multiplier, offset)) = self.mimic[b].clone() else {
                continue;
            };
            let follower = &self.model.bodies[b].joint;
            let bad = |why: &str| {
                Err(ModelError::Invalid(format!(
                    "mimic joint '{}' follows '{leader}': {why}",
                    follower.name
                )))
            };
            if follower.kind.nq() != 1 {
                return bad("only revolute, continuous and prismatic joints can mimic");
            }
            if !(multiplier.is_finite() && offset.is_finite()) {
                return bad("its multiplier and offset must be finite");
            }
            let Some(&l) = body_of.get(leader.as_str()) else {
                return bad("there is no moving joint of that name");
            };
            if self.mimic[l].is_some() {
                return bad(
                    "the leader is itself a mimic joint (chains of mimic joints are not supported)",
                );
            }
            if self.model.bodies[l].joint.kind.nq() != 1 {
                return bad("the leader must be a revolute, continuous or prismatic joint");
            }
            let lead = self.model.bodies[l].joint.coords;
            let joint = &mut self.model.bodies[b].joint;
            joint.coords = CoordinateMap {
                q_index: lead.q_index,
                v_index: lead.v_index,
                scale: multiplier,
                offset,
            };
            joint.mimics = Some(Mimic {
                leader,
                multiplier,
                offset,
            });
        }
        self.model.dof_parent = (!self.model.has_mimic()).then(|| dof_parents(&self.model));
        Ok(())
    }
}

/// Featherstone's `λ` over degrees of freedom: dof `k` of a joint hangs from dof `k − 1` of the
/// same joint, and its first dof from the last dof of the parent body's joint.
fn dof_parents(model: &Model) -> Vec<Option<usize>> {
    let mut parent = vec![None; model.nv];
    for body in &model.bodies {
        let c = body.joint.coords;
        for k in 0..body.joint.kind.nv() {
            parent[c.v_index + k] = if k > 0 {
                Some(c.v_index + k - 1)
            } else {
                body.parent.map(|p| {
                    let pc = model.bodies[p].joint.coords;
                    pc.v_index + model.bodies[p].joint.kind.nv() - 1
                })
            };
        }
    }
    parent
}

/// Refuses a model whose workspace would take more than [`Workspace::MAX_BYTES`], before any
/// workspace is made for it.
fn check_footprint(model: &Model) -> Result<(), ModelError> {
    let footprint = Workspace::footprint(model);
    if footprint.total() <= Workspace::MAX_BYTES {
        return Ok(());
    }
    let gb = |bytes: usize| bytes as f64 / 1e9;
    Err(ModelError::Invalid(format!(
        "the model has {} bodies and {} coordinates: a workspace for it would take about {:.1} GB \
         ({:.1} GB of nv × nv matrices, {:.1} GB of ancestor and support lists, which grow as the \
         square of the tree's depth), more than the {:.1} GB a model may need",
        model.nbodies(),
        model.nv,
        gb(footprint.total()),
        gb(footprint.matrices),
        gb(footprint.lists),
        gb(Workspace::MAX_BYTES)
    )))
}

fn inertia_is_finite(i: &crate::spatial::Inertia) -> bool {
    i.mass.is_finite() && i.h.iter().chain(i.i_bar.iter()).all(|x| x.is_finite())
}

/// A link's mass must be finite and non-negative, its inertia finite.
fn check_inertia(link: &BodySpec) -> Result<(), ModelError> {
    let i = &link.inertia;
    if !(i.mass.is_finite() && i.mass >= 0.0) {
        return Err(ModelError::Invalid(format!(
            "link '{}': mass must be finite and not negative, got {:e}",
            link.name, i.mass
        )));
    }
    if !(i.h.iter().chain(i.i_bar.iter()).all(|x| x.is_finite())) {
        return Err(ModelError::Invalid(format!(
            "link '{}': inertia or centre of mass is not finite",
            link.name
        )));
    }
    Ok(())
}

/// Physical doubts about a link's inertia (massive or not) that real URDFs do have (so they warn
/// rather than refuse): rotational inertia about the centre of mass not positive semi-definite,
/// or principal moments breaking the triangle inequality `I1 + I2 ≥ I3`.
fn inertia_doubts(link: &BodySpec) -> Option<String> {
    let i = &link.inertia;
    // I_c = Ī + m c× c× = Ī + h× h× / m; without mass, Ī itself.
    let i_com = if i.mass > 0.0 {
        let hx = crate::spatial::skew(&i.h);
        i.i_bar + hx * hx / i.mass
    } else {
        i.i_bar
    };
    if i_com.iter().all(|x| *x == 0.0) {
        return None;
    }
    let mut moments = nalgebra::SymmetricEigen::new(i_com).eigenvalues;
    moments.as_mut_slice().sort_by(f64::total_cmp);
    let scale = moments[2].abs().max(f64::MIN_POSITIVE);
    if moments[0] < -1e-9 * scale {
        Some(format!("link '{}': its rotational inertia is not positive semi-definite (principal moments {:.3e}, {:.3e}, {:.3e})", link.name, moments[0], moments[1], moments[2]))
    } else if moments[0] + moments[1] < moments[2] * (1.0 - 1e-6) {
        Some(format!("link '{}': its principal moments {:.3e}, {:.3e}, {:.3e} break the triangle inequality (no real body has them)", link.name, moments[0], moments[1], moments[2]))
    } else {
        None
    }
}
