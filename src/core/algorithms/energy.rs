//! Mechanical energy: kinetic `T = Σ ½ v_iᵀ I_i v_i` (= ½ q̇ᵀ H q̇) and potential
//! `V = −Σ m_i gᵀ c_i` (centres of mass in the world), with the model's gravity: by a
//! kinematics pass of their own ([`energy`]), or from what forward dynamics by ABA leaves in the
//! workspace ([`AbaEnergy`]).

use super::kinematics::{update_joints, update_placements, update_velocities};
use super::validate::{check_q, check_v};
use crate::error::DynamicsError;
use crate::instruction_set::run_pass;
use crate::model::Model;
use crate::spatial::{Inertia, Motion, Vector3};
use crate::Workspace;

/// `(T, V)` at `(q, v)`, in joules; the base is at rest in the world.
pub fn energy(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(f64, f64), DynamicsError> {
    check_q(model, ws, q)?;
    check_v(model, "v", v)?;
    energy_of_checked(model, ws, q, v)
}

/// [`energy`] for a caller that has checked `q` and `v` as it does: `ws` made for `model`,
/// the model's sizes, finite values, every floating joint's quaternion not (near) zero. The
/// sums are checked once at the end: a non-finite term keeps them non-finite.
pub(crate) fn energy_of_checked(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(f64, f64), DynamicsError> {
    run_pass!(energy_of_checked_in(model, ws, q, v))
}

/// [`energy_of_checked`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn energy_of_checked_in(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(f64, f64), DynamicsError> {
    update_joints(model, ws, q);
    update_placements(model, ws);
    update_velocities(model, ws, v);
    let (mut kinetic, mut potential) = (0.0, 0.0);
    for i in 0..model.bodies.len() {
        let (t, u) = body_energy(model, ws, i);
        kinetic += t;
        potential += u;
    }
    if kinetic.is_finite() && potential.is_finite() {
        Ok((kinetic, potential))
    } else {
        Err(first_non_finite(model, ws))
    }
}

/// Body `i`'s `(½ v_iᵀ I_i v_i, −m_i gᵀ c_i)` from the placements and velocities in `ws`.
#[inline(always)]
fn body_energy(model: &Model, ws: &Workspace, i: usize) -> (f64, f64) {
    let body = &model.bodies[i];
    let kinetic = 0.5 * ws.v[i].dot(&body.inertia.apply(&ws.v[i]));
    // Centre of mass in the world: r + Eᵀ c (E: world → body rotation, r: body origin).
    let x = &ws.x_world[i];
    let com_world = x.trans + x.rot.tr_mul(&body.inertia.com());
    (kinetic, -body.inertia.mass * model.gravity.dot(&com_world))
}

/// `(T, V)` at the state ABA was last evaluated at, from what its first pass leaves in the
/// workspace, with no kinematics of its own. That pass holds every quantity in *aligned frames*
/// (world axes, origin at an anchor body's origin; `kinematics::update_aligned_placements`): body
/// `i`'s velocity `v_i` (`ws.v_world[i]`) and its rigid inertia `I_i = (m_i, h_i, Ī_i)` about its
/// aligned frame's origin (`ws.ic[i]`; `h_i = m_i c_i`, `c_i` its centre of mass from that origin),
/// both in the same frame, so
/// ```text
/// T = ½ Σ_i v_iᵀ I_i v_i             (v_iᵀ I_i v_i by [`twice_kinetic`])
/// V = −gᵀ Σ_i (m_i p_i + h_i)
/// ```
/// with `p_i` the world position of body `i`'s aligned-frame origin: the sum of the shifts `r_a`
/// (`ws.anchor_shift[a]`, anchor `a`'s origin in its parent's aligned frame, a root's in the
/// world) of the anchors `a` on the path from its root to body `i`. Summed by anchor,
/// `Σ_i m_i p_i = Σ_a M_a r_a` with `M_a` the mass of anchor `a`'s subtree (constant, made once by
/// [`new`](Self::new)): one term per body and one per anchor, no per-body position.
pub(crate) struct AbaEnergy {
    /// Mass of each body's subtree, the body included (kg).
    subtree_mass: Vec<f64>,
}

impl AbaEnergy {
    /// The subtree masses of `model`'s bodies.
    pub(crate) fn new(model: &Model) -> AbaEnergy {
        let mut subtree_mass: Vec<f64> = model.bodies.iter().map(|b| b.inertia.mass).collect();
        // Children come after their parent: from the leaves inward, each subtree is complete
        // when it is added to its parent's.
        for (i, body) in model.bodies.iter().enumerate().rev() {
            if let Some(p) = body.parent {
                subtree_mass[p] += subtree_mass[i];
            }
        }
        AbaEnergy { subtree_mass }
    }

    /// `(T, V)` (J) from `ws` after ABA's first pass at a state of `model` (the model this was
    /// made for); `None` when a sum is not finite (the state's [`energy_of_checked`] names the
    /// body).
    pub(crate) fn of(&self, model: &Model, ws: &Workspace) -> Option<(f64, f64)> {
        let n = model.bodies.len();
        let (mut kinetic, mut first_moment) = (0.0, Vector3::zeros());
        let bodies = ws.v_world[..n].iter().zip(&ws.ic[..n]);
        let frames = ws.plan.anchors[..n].iter().zip(&ws.anchor_shift[..n]);
        for ((v, inertia), ((&anchor, shift), mass)) in
            bodies.zip(frames.zip(&self.subtree_mass[..n]))
        {
            kinetic += twice_kinetic(inertia, v);
            first_moment += inertia.h;
            if anchor {
                first_moment += shift * *mass;
            }
        }
        let (kinetic, potential) = (0.5 * kinetic, -model.gravity.dot(&first_moment));
        (kinetic.is_finite() && potential.is_finite()).then_some((kinetic, potential))
    }
}

/// `vᵀ I v` for a rigid inertia `I = (m, h, Ī)` and a velocity `v = [ω; v_O]` in the same frame,
/// by its terms: `I v = [Ī ω + h × v_O; m v_O − h × ω]` gives
/// `vᵀ I v = ωᵀ Ī ω + 2 ω · (h × v_O) + m |v_O|²`, with `ωᵀ Ī ω` over `Ī`'s six distinct
/// entries (it is symmetric).
#[inline(always)]
fn twice_kinetic(inertia: &Inertia, v: &Motion) -> f64 {
    let (w, i) = (&v.ang, &inertia.i_bar);
    let diagonal = i[(0, 0)] * w.x * w.x + i[(1, 1)] * w.y * w.y + i[(2, 2)] * w.z * w.z;
    let off_diagonal = i[(0, 1)] * w.x * w.y + i[(0, 2)] * w.x * w.z + i[(1, 2)] * w.y * w.z;
    diagonal
        + 2.0 * (off_diagonal + w.dot(&inertia.h.cross(&v.lin)))
        + inertia.mass * v.lin.norm_squared()
}

/// The error for finite inputs whose energy overflows (½ m v² at v = 1e200), naming the joint
/// of the first body at which a partial sum stops being finite.
#[cold]
fn first_non_finite(model: &Model, ws: &Workspace) -> DynamicsError {
    let (mut kinetic, mut potential) = (0.0, 0.0);
    for (i, body) in model.bodies.iter().enumerate() {
        let (t, u) = body_energy(model, ws, i);
        kinetic += t;
        potential += u;
        for (quantity, value) in [("kinetic energy", kinetic), ("potential energy", potential)] {
            if !value.is_finite() {
                return DynamicsError::NonFiniteResult {
                    quantity,
                    coordinate: body.joint.name.clone(),
                };
            }
        }
    }
    // Not reached: the same sums, in the same order, are not finite.
    let last = model
        .bodies
        .last()
        .map_or(String::new(), |b| b.joint.name.clone());
    DynamicsError::NonFiniteResult {
        quantity: "energy",
        coordinate: last,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::{aba, Externals};
    use crate::model::examples::{pendulum_urdf, DEFAULT_ARM_URDF};
    use crate::sampling::{random_q, Rng};
    use crate::urdf::model_from_str;
    use crate::ModelOptions;

    const TREE: &str = include_str!("../tests/models/tree.urdf");
    const QUARTER_TURNS: &str = include_str!("../tests/models/quarter_turns.urdf");

    /// How far a far model's root stands from the world origin (m).
    const FAR: [f64; 3] = [1000.0, -700.0, 300.0];

    fn load(text: &str, floating_base: bool) -> Model {
        let options = ModelOptions {
            floating_base,
            ..Default::default()
        };
        model_from_str(text, &options).unwrap()
    }

    /// `TREE` hung from a carriage on a rail along x (±2 km): its planar joint below the root
    /// travels without bound, so the torso anchors a frame of its own below the carriage's.
    fn tree_on_a_rail() -> String {
        TREE.replacen(
            r#"<parent link="world"/><child link="torso"/>"#,
            r#"<parent link="carriage"/><child link="torso"/>"#,
            1,
        )
        .replacen(
            "<link name=\"world\"/>\n",
            r#"<link name="world"/>
  <joint name="rail" type="prismatic"><parent link="world"/><child link="carriage"/>
    <origin xyz="0.2 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-2000" upper="2000" effort="1" velocity="1"/></joint>
  <link name="carriage"><inertial><mass value="3"/>
    <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link>
"#,
            1,
        )
    }

    /// `(T, V)` from ABA's workspace ([`AbaEnergy`]) equal the kinematics pass's ([`energy`])
    /// to 1e-12 relative, at random states of fixed, floating, branched and long models, near
    /// the world origin and a kilometre from it (where `V` is about `M gᵀ p` with `|p|` a
    /// kilometre: a wrong frame origin `p_i` shows there). The tree on a rail, the default arm, the
    /// quarter turns and the chain of 24 links of 1 m anchor frames below their roots, so the
    /// anchors' shifts are summed down the tree (on the rail, 1.5 km out and across a branch).
    #[test]
    fn the_energy_from_abas_workspace_is_the_kinematics_passes() {
        let chain = pendulum_urdf(24, 1.0, 1.0);
        let tree_floating_joint = TREE.replace(r#"type="planar""#, r#"type="floating""#);
        let near = |_: &mut [f64]| {};
        let far = |q: &mut [f64]| q[..3].copy_from_slice(&FAR);
        let along_the_rail = |q: &mut [f64]| q[0] = 1500.0;
        type Case<'a> = (&'a str, Model, &'a dyn Fn(&mut [f64]), bool);
        let cases: [Case; 8] = [
            ("default arm", load(DEFAULT_ARM_URDF, false), &near, false),
            (
                "default arm, floating base",
                load(DEFAULT_ARM_URDF, true),
                &near,
                false,
            ),
            (
                "default arm, floating base far away",
                load(DEFAULT_ARM_URDF, true),
                &far,
                false,
            ),
            ("tree", load(TREE, false), &near, false),
            (
                "tree, floating joint far away",
                load(&tree_floating_joint, false),
                &far,
                false,
            ),
            (
                "tree on a rail, 1.5 km along it",
                load(&tree_on_a_rail(), false),
                &along_the_rail,
                true,
            ),
            ("quarter turns", load(QUARTER_TURNS, false), &near, false),
            ("chain of 24", load(&chain, false), &near, true),
        ];
        let mut rng = Rng::new(29);
        for (name, model, place, interior_anchors) in &cases {
            let (mut ws, mut ws_ref) = (Workspace::new(model), Workspace::new(model));
            let from_aba = AbaEnergy::new(model);
            let below_roots = (0..model.bodies.len())
                .filter(|&i| ws.plan.anchors[i] && model.bodies[i].parent.is_some())
                .count();
            assert!(
                below_roots > 0 || !interior_anchors,
                "{name}: no anchor below a root"
            );
            for _ in 0..4 {
                let mut q = random_q(model, &mut rng);
                place(&mut q);
                let v = rng.vector(model.nv, 2.0);
                let tau = rng.vector(model.nv, 1.0);
                aba(model, &mut ws, &q, &v, &tau, &Externals::none()).unwrap();
                let (kinetic, potential) = from_aba.of(model, &ws).unwrap();
                let (kinetic_ref, potential_ref) = energy(model, &mut ws_ref, &q, &v).unwrap();
                for (what, x, reference) in
                    [("T", kinetic, kinetic_ref), ("V", potential, potential_ref)]
                {
                    let error = (x - reference).abs() / reference.abs();
                    assert!(
                        error < 1e-12,
                        "{name}: {what} = {x} J, by kinematics {reference} J (relative error {error:e})"
                    );
                }
            }
        }
    }
}
