//! Frame kinematics against independent references: finite differences of placements along
//! trajectories (`J q̇` is the derivative of the placement; the classical acceleration is the
//! derivative of `J q̇`), closed forms on a double pendulum with a fused tool, the full model
//! at the locked positions for reduced models, the mimic map for mimic joints, and the centre
//! of mass summed body by body from `body_placements`.

mod common;

use common::{random_q, Rng};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use spatial_dynamics_core::algorithms::kinematics::body_placements;
use spatial_dynamics_core::algorithms::{
    center_of_mass, center_of_mass_jacobian, find_frame, frame_classical_acceleration,
    frame_jacobian, frame_placement, joint_jacobians, Frame, ReferenceFrame,
};
use spatial_dynamics_core::model::examples::{pendulum_urdf, DEFAULT_ARM_URDF, MIMIC_GRIPPER_URDF};
use spatial_dynamics_core::{urdf, DynamicsError, Model, ModelOptions, Workspace};

const TREE: &str = include_str!("models/tree.urdf");
const QUARTER_TURNS: &str = include_str!("models/quarter_turns.urdf");
const REFERENCES: [ReferenceFrame; 3] = [
    ReferenceFrame::World,
    ReferenceFrame::Local,
    ReferenceFrame::LocalWorldAligned,
];

fn load(text: &str, options: ModelOptions) -> Model {
    urdf::model_from_str(text, &options).unwrap_or_else(|e| panic!("{options:?}: {e}"))
}

/// Models covering every joint kind and frame situation: revolute, continuous and prismatic
/// joints, a planar base (whose `S` turns with θ), a URDF floating joint and `--floating-base`,
/// body frames turned by quarter turns, links fused through fixed joints, mimic joints, and a
/// model reduced by a tip and a lock (links lumped onto kept bodies).
fn models() -> Vec<(&'static str, Model)> {
    let floating = ModelOptions {
        floating_base: true,
        ..Default::default()
    };
    let reduced = ModelOptions {
        tips: vec!["link5".into()],
        locked: vec![("joint2".into(), 0.4)],
        ..Default::default()
    };
    vec![
        (
            "default arm",
            load(DEFAULT_ARM_URDF, ModelOptions::default()),
        ),
        ("tree (planar base)", load(TREE, ModelOptions::default())),
        (
            "tree (floating joint)",
            load(
                &TREE.replace(r#"type="planar""#, r#"type="floating""#),
                ModelOptions::default(),
            ),
        ),
        (
            "tree (floating joint under a floating base)",
            load(
                &TREE.replace(r#"type="planar""#, r#"type="floating""#),
                floating.clone(),
            ),
        ),
        (
            "quarter turns",
            load(QUARTER_TURNS, ModelOptions::default()),
        ),
        (
            "quarter turns, floating base",
            load(QUARTER_TURNS, floating),
        ),
        (
            "mimic gripper",
            load(MIMIC_GRIPPER_URDF, ModelOptions::default()),
        ),
        ("default arm reduced", load(DEFAULT_ARM_URDF, reduced)),
    ]
}

/// Runs `check(name, model, ws, rng, q0)` on every model of [`models`] at three random
/// configurations `q0` drawn from `Rng::new(seed)`.
fn at_random_configurations(
    seed: u64,
    mut check: impl FnMut(&str, &Model, &mut Workspace, &mut Rng, &[f64]),
) {
    for (name, model) in models() {
        let mut ws = Workspace::new(&model);
        let mut rng = Rng::new(seed);
        for _ in 0..3 {
            let q0 = random_q(&model, &mut rng);
            check(name, &model, &mut ws, &mut rng, &q0);
        }
    }
}

/// `(p, R)`: the link origin in the world and the link axes in world coordinates.
fn pose(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    frame: &Frame,
) -> (Vector3<f64>, Matrix3<f64>) {
    let x = frame_placement(model, ws, q, frame).unwrap();
    (x.trans, x.rot.transpose())
}

/// `q(t) = q₀ ⊕ q̇ t`: constant velocity on each joint's manifold (a floating base moves with a
/// constant twist in its own frame, so `q̈ = 0` along it).
fn along(model: &Model, q0: &[f64], v: &[f64], t: f64) -> Vec<f64> {
    let mut q = vec![0.0; model.nq()];
    model.integrate(q0, v, t, &mut q).unwrap();
    q
}

/// `f'(0)` by the fourth-order central difference with step `h`.
fn derivative(mut f: impl FnMut(f64) -> DVector<f64>, h: f64) -> DVector<f64> {
    (f(-2.0 * h) - f(2.0 * h) + (f(h) - f(-h)) * 8.0) / (12.0 * h)
}

/// The angular velocity `ω` with `Ṙ Rᵀ = ω×` (the antisymmetric part, averaged).
fn angular_velocity(r: &Matrix3<f64>, r_dot: &Matrix3<f64>) -> Vector3<f64> {
    let w = r_dot * r.transpose();
    Vector3::new(
        w[(2, 1)] - w[(1, 2)],
        w[(0, 2)] - w[(2, 0)],
        w[(1, 0)] - w[(0, 1)],
    ) * 0.5
}

fn twist(lin: Vector3<f64>, ang: Vector3<f64>) -> DVector<f64> {
    DVector::from_iterator(6, lin.iter().chain(ang.iter()).copied())
}

fn assert_close(what: &str, got: &DVector<f64>, want: &DVector<f64>, tol: f64) {
    let err = (got - want).amax();
    assert!(
        err <= tol * want.amax().max(1.0),
        "{what}: got {got:.12?}, want {want:.12?}, error {err:e}"
    );
}

/// `J q̇`, in each reference, is the twist found by differentiating the frame's placement
/// along `q(t) = q₀ ⊕ q̇ t`: `ṗ` and `Ṙ Rᵀ = ω×` give `[ṗ; ω]` (local world aligned),
/// `[ṗ − ω × p; ω]` (world) and `[Rᵀ ṗ; Rᵀ ω]` (local). Every link of every model is a frame,
/// fused, lumped and fixed-to-the-world ones included; the one-pass joint Jacobians give the
/// same matrices.
#[test]
fn jacobian_times_velocity_is_the_derivative_of_the_placement() {
    let h = 1e-3;
    at_random_configurations(11, |name, model, ws, rng, q0| {
        let v = rng.vector(model.nv(), 1.5);
        let v_col = DVector::from_column_slice(&v);
        for link in model.links() {
            let frame = find_frame(model, &link.name).unwrap();
            let mut at = |t: f64| {
                let (p, r) = pose(model, ws, &along(model, q0, &v, t), &frame);
                DVector::from_iterator(12, p.iter().chain(r.iter()).copied())
            };
            let rates = derivative(&mut at, h);
            let now = at(0.0);
            let p = Vector3::from_column_slice(&now.as_slice()[..3]);
            let r = Matrix3::from_column_slice(&now.as_slice()[3..]);
            let p_dot = Vector3::from_column_slice(&rates.as_slice()[..3]);
            let omega = angular_velocity(&r, &Matrix3::from_column_slice(&rates.as_slice()[3..]));
            let want = |reference| match reference {
                ReferenceFrame::World => twist(p_dot - omega.cross(&p), omega),
                ReferenceFrame::LocalWorldAligned => twist(p_dot, omega),
                ReferenceFrame::Local => twist(r.transpose() * p_dot, r.transpose() * omega),
            };
            for reference in REFERENCES {
                let j = frame_jacobian(model, ws, q0, &frame, reference)
                    .unwrap()
                    .clone();
                let what = format!("{name}, link {}, {reference:?}", link.name);
                assert_close(&what, &(&j * &v_col), &want(reference), 1e-8);
                let mut all = joint_jacobians(model, ws, q0).unwrap();
                let from_joints = all.frame_jacobian(&frame, reference).unwrap();
                let err = (from_joints - &j).amax();
                assert!(
                    err <= 1e-14 * j.amax().max(1.0),
                    "{what}: joint Jacobians differ by {err:e}"
                );
            }
        }
    });
}

/// The classical acceleration is the derivative of the frame's `[ṗ; ω]` (`J q̇` in local world
/// aligned): along `q(t) = q₀ + q̇₀ t + ½ q̈ t²` for fixed bases, along `q₀ ⊕ q̇ t` (`q̈ = 0`, so
/// `J̇ q̇`) for floating ones, where `q̈` then enters through `J q̈` (the acceleration is affine
/// in `q̈`). In local axes it is the same vector turned by `Rᵀ`.
#[test]
fn classical_acceleration_is_the_derivative_of_the_frame_velocity() {
    let h = 1e-3;
    at_random_configurations(12, |name, model, ws, rng, q0| {
        let floating = model.nq() != model.nv();
        let (v0, a) = (rng.vector(model.nv(), 1.5), rng.vector(model.nv(), 2.0));
        let zeros = vec![0.0; model.nv()];
        // q(t), q̇(t): the trajectory the acceleration `a_traj` is the second derivative of.
        let a_traj = if floating { zeros.clone() } else { a.clone() };
        let state = |t: f64| -> (Vec<f64>, Vec<f64>) {
            if floating {
                (along(model, q0, &v0, t), v0.clone())
            } else {
                let q = (0..model.nq()).map(|k| q0[k] + v0[k] * t + 0.5 * a_traj[k] * t * t);
                let v = (0..model.nv()).map(|k| v0[k] + a_traj[k] * t);
                (q.collect(), v.collect())
            }
        };
        for link in model.links() {
            let frame = find_frame(model, &link.name).unwrap();
            let mut velocity = |t: f64| {
                let (q, v) = state(t);
                let j = frame_jacobian(model, ws, &q, &frame, ReferenceFrame::LocalWorldAligned)
                    .unwrap();
                j * DVector::from_column_slice(&v)
            };
            let want = derivative(&mut velocity, h);
            let what = format!("{name}, link {}", link.name);
            let lwa = ReferenceFrame::LocalWorldAligned;
            let acc = |ws: &mut Workspace, a: &[f64], reference| {
                let m =
                    frame_classical_acceleration(model, ws, q0, &v0, a, &frame, reference).unwrap();
                twist(m.lin, m.ang)
            };
            let got = acc(ws, &a_traj, lwa);
            assert_close(&format!("{what}: d(J q̇)/dt"), &got, &want, 1e-8);
            // Affine in q̈: the rest of `a` enters through J (a − a_traj).
            let j = frame_jacobian(model, ws, q0, &frame, lwa).unwrap().clone();
            let extra: Vec<f64> = a.iter().zip(&a_traj).map(|(x, y)| x - y).collect();
            let full = acc(ws, &a, lwa);
            let want_full = &got + &j * DVector::from_column_slice(&extra);
            assert_close(&format!("{what}: J q̈ part"), &full, &want_full, 1e-12);
            let (_, r) = pose(model, ws, q0, &frame);
            let local = acc(ws, &a, ReferenceFrame::Local);
            let turned = twist(
                r.transpose() * Vector3::from_column_slice(&full.as_slice()[..3]),
                r.transpose() * Vector3::from_column_slice(&full.as_slice()[3..]),
            );
            assert_close(&format!("{what}: local"), &local, &turned, 1e-12);
        }
    });
}

/// A double pendulum about y (links of length `l` along −z from each joint) with a tool fused
/// to link 2 through a fixed joint at `(t_x, 0, t_z)`, turned by 0.3 rad about y. Closed forms:
/// `p₂ = (−l s₁, 0, −l c₁)`, `R₂ = R_y(q₁ + q₂)`, the tool at `p₂ + R₂ t`, `R_y(q₁ + q₂ + 0.3)`.
#[test]
fn double_pendulum_with_a_fused_tool_matches_closed_forms() {
    let (l, m, tx, tz) = (0.7, 1.3, 0.1, -0.25);
    let text = pendulum_urdf(2, l, m).replace(
        "</robot>",
        &format!(
            r#"<joint name="tool_mount" type="fixed"><parent link="link2"/><child link="tool"/>
                 <origin xyz="{tx} 0 {tz}" rpy="0 0.3 0"/></joint>
               <link name="tool"/></robot>"#
        ),
    );
    let model = load(&text, ModelOptions::default());
    let mut ws = Workspace::new(&model);
    let ry = |a: f64| Matrix3::new(a.cos(), 0.0, a.sin(), 0.0, 1.0, 0.0, -a.sin(), 0.0, a.cos());
    let y = Vector3::y();
    let tool = find_frame(&model, "tool").unwrap();
    let link2 = find_frame(&model, "link2").unwrap();
    let mut rng = Rng::new(3);
    for _ in 0..10 {
        let (q, v, a) = (rng.vector(2, 3.0), rng.vector(2, 2.0), rng.vector(2, 2.0));
        let (s1, c1) = q[0].sin_cos();
        let q12 = q[0] + q[1];
        let p2 = Vector3::new(-l * s1, 0.0, -l * c1);
        let r2 = ry(q12);
        let offset = r2 * Vector3::new(tx, 0.0, tz);
        let p_tool = p2 + offset;
        // Placements.
        let (p, r) = pose(&model, &mut ws, &q, &tool);
        assert!((p - p_tool).amax() < 1e-15 && (r - ry(q12 + 0.3)).amax() < 1e-15);
        // LWA Jacobian: column 1 turns everything about the world origin's y axis, column 2
        // turns the tool about link 2's origin.
        let col1 = y.cross(&p_tool);
        let col2 = y.cross(&offset);
        let want_lwa = DMatrix::from_column_slice(
            6,
            2,
            &[
                col1.x, col1.y, col1.z, 0.0, 1.0, 0.0, col2.x, col2.y, col2.z, 0.0, 1.0, 0.0,
            ],
        );
        let j = frame_jacobian(
            &model,
            &mut ws,
            &q,
            &tool,
            ReferenceFrame::LocalWorldAligned,
        )
        .unwrap();
        assert!((j - &want_lwa).amax() < 1e-15, "LWA {j} vs {want_lwa}");
        // World: the point at the world origin; joint 1's axis passes through it.
        let col2_world = y.cross(&(-p2));
        let want_world = DMatrix::from_column_slice(
            6,
            2,
            &[
                0.0,
                0.0,
                0.0,
                0.0,
                1.0,
                0.0,
                col2_world.x,
                col2_world.y,
                col2_world.z,
                0.0,
                1.0,
                0.0,
            ],
        );
        let j = frame_jacobian(&model, &mut ws, &q, &tool, ReferenceFrame::World).unwrap();
        assert!(
            (j - &want_world).amax() < 1e-15,
            "world {j} vs {want_world}"
        );
        // Local: the tool's axes.
        let rt = ry(q12 + 0.3).transpose();
        let mut want_local = want_lwa.clone();
        for k in 0..2 {
            let lin = rt * Vector3::new(want_lwa[(0, k)], want_lwa[(1, k)], want_lwa[(2, k)]);
            want_local.fixed_view_mut::<3, 1>(0, k).copy_from(&lin);
        }
        let j = frame_jacobian(&model, &mut ws, &q, &tool, ReferenceFrame::Local).unwrap();
        assert!(
            (j - &want_local).amax() < 1e-15,
            "local {j} vs {want_local}"
        );
        // Classical acceleration of link 2's origin: p̈₂ = (l s₁ q̇₁² − l c₁ q̈₁, 0, l c₁ q̇₁² + l s₁ q̈₁),
        // ω̇ = (q̈₁ + q̈₂) y; of the tool: p̈₂ + ω̇ × o + ω × (ω × o), o = R₂ t.
        let acc = frame_classical_acceleration(
            &model,
            &mut ws,
            &q,
            &v,
            &a,
            &link2,
            ReferenceFrame::LocalWorldAligned,
        )
        .unwrap();
        let p2_acc = Vector3::new(
            l * s1 * v[0] * v[0] - l * c1 * a[0],
            0.0,
            l * c1 * v[0] * v[0] + l * s1 * a[0],
        );
        let (w, w_dot) = (y * (v[0] + v[1]), y * (a[0] + a[1]));
        assert!(
            (acc.lin - p2_acc).amax() < 1e-14 && (acc.ang - w_dot).amax() < 1e-15,
            "link2 {acc:?}"
        );
        let acc = frame_classical_acceleration(
            &model,
            &mut ws,
            &q,
            &v,
            &a,
            &tool,
            ReferenceFrame::LocalWorldAligned,
        )
        .unwrap();
        let tool_acc = p2_acc + w_dot.cross(&offset) + w.cross(&w.cross(&offset));
        assert!(
            (acc.lin - tool_acc).amax() < 1e-14,
            "tool {acc:?} vs {tool_acc}"
        );
        // Centre of mass: each rod's at its middle.
        let c1_pos = Vector3::new(-0.5 * l * s1, 0.0, -0.5 * l * c1);
        let c2_pos = p2 + r2 * Vector3::new(0.0, 0.0, -0.5 * l);
        let (com, jc) = center_of_mass_jacobian(&model, &mut ws, &q).unwrap();
        assert!((com.mass - 2.0 * m).abs() < 1e-15);
        assert!((com.position - (c1_pos + c2_pos) / 2.0).amax() < 1e-15);
        let jc1 = (y.cross(&c1_pos) + y.cross(&c2_pos)) / 2.0;
        let jc2 = y.cross(&(c2_pos - p2)) / 2.0;
        let want_jc = DMatrix::from_column_slice(3, 2, &[jc1.x, jc1.y, jc1.z, jc2.x, jc2.y, jc2.z]);
        assert!((jc - &want_jc).amax() < 1e-15, "J_com {jc} vs {want_jc}");
    }
}

/// The centre of mass is the mass-weighted mean of the bodies' centres placed by
/// `body_placements`, and `J_c q̇` is its derivative along `q₀ ⊕ q̇ t`.
#[test]
fn center_of_mass_and_its_jacobian() {
    let h = 1e-3;
    at_random_configurations(13, |name, model, ws, rng, q0| {
        let v = rng.vector(model.nv(), 1.5);
        let placements = body_placements(model, ws, q0).unwrap().to_vec();
        let (mut mass, mut moment) = (0.0, Vector3::zeros());
        for (body, x) in model.bodies().iter().zip(&placements) {
            let c = x.trans + x.rot.transpose() * body.inertia.com();
            mass += body.inertia.mass;
            moment += c * body.inertia.mass;
        }
        let (com, jc) = center_of_mass_jacobian(model, ws, q0).unwrap();
        let jc = jc.clone();
        assert!((com.mass - mass).abs() <= 1e-14 * mass, "{name}: mass");
        assert!((com.position - moment / mass).amax() < 1e-14, "{name}: com");
        assert_eq!(center_of_mass(model, ws, q0).unwrap(), com);
        let rate = derivative(
            |t| {
                let c = center_of_mass(model, &mut Workspace::new(model), &along(model, q0, &v, t))
                    .unwrap();
                DVector::from_column_slice(c.position.as_slice())
            },
            h,
        );
        assert_close(
            &format!("{name}: J_c q̇"),
            &(&jc * DVector::from_column_slice(&v)),
            &rate,
            1e-8,
        );
    });
}

/// `Workspace::world_to_body` is each body's placement from the last call that placed it: every
/// body after the centre of mass (where `body_placements` puts them), and after a frame's
/// placement at another configuration the bodies supporting the frame there (the frame where
/// they put it) while the others keep theirs.
#[test]
fn world_to_body_is_the_last_placement_of_each_body() {
    at_random_configurations(17, |name, model, ws, rng, q0| {
        let q1 = random_q(model, rng);
        let placed = |q: &[f64]| {
            body_placements(model, &mut Workspace::new(model), q)
                .unwrap()
                .to_vec()
        };
        let (at_q0, at_q1) = (placed(q0), placed(&q1));
        for link in model.links() {
            let Some(body) = link.body else { continue };
            center_of_mass(model, ws, q0).unwrap();
            for (i, x) in at_q0.iter().enumerate() {
                assert_eq!(
                    ws.world_to_body(i),
                    *x,
                    "{name}: body {i} after the centre of mass"
                );
            }
            let frame = find_frame(model, &link.name).unwrap();
            let x_link = frame_placement(model, ws, &q1, &frame).unwrap();
            assert_eq!(x_link, frame.x_body_link().compose(&ws.world_to_body(body)));
            let mut support = vec![false; model.nbodies()];
            let mut next = Some(body);
            while let Some(i) = next {
                support[i] = true;
                next = model.bodies()[i].parent;
            }
            for i in 0..model.nbodies() {
                let (got, want) = (
                    ws.world_to_body(i),
                    if support[i] { at_q1[i] } else { at_q0[i] },
                );
                let error = (got.rot - want.rot)
                    .amax()
                    .max((got.trans - want.trans).amax());
                let scale = 1.0 + want.trans.amax();
                assert!(
                    error <= 1e-14 * scale,
                    "{name}: body {i} after the placement of '{}': {error:e}",
                    link.name
                );
            }
        }
    });
}

/// A reduced model's frames sit where the full model's do with the removed joints at their
/// locked or frozen positions, and their Jacobians are the full model's kept columns; links
/// lumped onto a tip, locked away, or fixed to the world (whose Jacobian is zero) included.
#[test]
fn reduced_models_keep_every_link_as_a_frame() {
    let full = load(DEFAULT_ARM_URDF, ModelOptions::default());
    let options = ModelOptions {
        root: Some("link1".into()),
        tips: vec!["link5".into()],
        locked: vec![("joint1".into(), -0.6), ("joint3".into(), 0.4)],
        ..Default::default()
    };
    let reduced = load(DEFAULT_ARM_URDF, options);
    assert!(reduced.nv() < full.nv());
    let (mut ws_full, mut ws) = (Workspace::new(&full), Workspace::new(&reduced));
    let held: Vec<(String, f64)> = reduced
        .locked_joints()
        .iter()
        .cloned()
        .chain(
            reduced
                .reduction()
                .frozen_joints
                .iter()
                .map(|(n, p)| (n.clone(), p[0])),
        )
        .collect();
    let slot = |model: &Model, name: &str| {
        let j = model.coordinate_joints().find(|j| j.name == name).unwrap();
        (j.q_index, j.v_index)
    };
    let mut rng = Rng::new(5);
    for _ in 0..5 {
        let q = random_q(&reduced, &mut rng);
        let mut q_full = vec![0.0; full.nq()];
        let mut columns = Vec::new();
        for j in reduced.coordinate_joints() {
            let (fq, fv) = slot(&full, j.name);
            q_full[fq] = q[j.q_index];
            columns.push(fv);
        }
        for (name, position) in &held {
            q_full[slot(&full, name).0] = *position;
        }
        let mut world_fixed = 0;
        for link in full.links() {
            let frame = find_frame(&reduced, &link.name).unwrap();
            world_fixed += frame.body().is_none() as usize;
            let full_frame = find_frame(&full, &link.name).unwrap();
            let x = frame_placement(&reduced, &mut ws, &q, &frame).unwrap();
            let y = frame_placement(&full, &mut ws_full, &q_full, &full_frame).unwrap();
            assert!(
                (x.rot - y.rot).amax() < 1e-14 && (x.trans - y.trans).amax() < 1e-14,
                "{}",
                link.name
            );
            for reference in REFERENCES {
                let j = frame_jacobian(&reduced, &mut ws, &q, &frame, reference)
                    .unwrap()
                    .clone();
                let j_full =
                    frame_jacobian(&full, &mut ws_full, &q_full, &full_frame, reference).unwrap();
                for (k, &fv) in columns.iter().enumerate() {
                    let err = (j.column(k) - j_full.column(fv)).amax();
                    assert!(
                        err < 1e-14,
                        "{} {reference:?} column {k}: {err:e}",
                        link.name
                    );
                }
            }
        }
        // base_link and link1 (below the new root) never move.
        assert!(world_fixed >= 2);
    }
}

/// With mimic joints honoured, a follower's column adds to its leader's with the multiplier:
/// `J = J_independent G`, `G` the mimic map (`q̇_follower = μ q̇_leader`).
#[test]
fn mimic_followers_add_to_their_leaders_columns() {
    let mimic = load(MIMIC_GRIPPER_URDF, ModelOptions::default());
    let plain = load(
        MIMIC_GRIPPER_URDF,
        ModelOptions {
            ignore_mimic: true,
            ..Default::default()
        },
    );
    let (mut ws, mut ws_plain) = (Workspace::new(&mimic), Workspace::new(&plain));
    // G from the URDF's tags (finger_right = 1.0 finger_left, thumb = −0.5 wrist + 0.1).
    let tags = [
        ("finger_right", "finger_left", 1.0, 0.0),
        ("thumb", "wrist", -0.5, 0.1),
    ];
    let index = |model: &Model, name: &str| {
        model
            .coordinate_joints()
            .find(|j| j.name == name)
            .unwrap()
            .v_index
    };
    let mut g = DMatrix::zeros(plain.nv(), mimic.nv());
    for j in mimic.coordinate_joints() {
        g[(index(&plain, j.name), j.v_index)] = 1.0;
    }
    for (follower, leader, mu, _) in tags {
        g[(index(&plain, follower), index(&mimic, leader))] = mu;
    }
    let mut rng = Rng::new(8);
    for _ in 0..5 {
        let q = random_q(&mimic, &mut rng);
        let mut q_plain = vec![0.0; plain.nq()];
        for j in mimic.coordinate_joints() {
            q_plain[index(&plain, j.name)] = q[j.q_index];
        }
        for (follower, leader, mu, offset) in tags {
            q_plain[index(&plain, follower)] = mu * q[index(&mimic, leader)] + offset;
        }
        for link in mimic.links() {
            let (f, fp) = (
                find_frame(&mimic, &link.name).unwrap(),
                find_frame(&plain, &link.name).unwrap(),
            );
            for reference in REFERENCES {
                let j = frame_jacobian(&mimic, &mut ws, &q, &f, reference)
                    .unwrap()
                    .clone();
                let want =
                    frame_jacobian(&plain, &mut ws_plain, &q_plain, &fp, reference).unwrap() * &g;
                assert!(
                    (&j - &want).amax() < 1e-14,
                    "{} {reference:?}: {j} vs {want}",
                    link.name
                );
            }
        }
        let (_, jc) = center_of_mass_jacobian(&mimic, &mut ws, &q).unwrap();
        let jc = jc.clone();
        let want = center_of_mass_jacobian(&plain, &mut ws_plain, &q_plain)
            .unwrap()
            .1
            * &g;
        assert!((jc - want).amax() < 1e-14);
    }
}

/// Unknown and pruned links are errors naming them and listing the links; bad vectors are
/// refused; the classical acceleration in `world` and the centre of mass of a massless model
/// are refused rather than answered with something meaningless.
#[test]
fn bad_requests_are_errors_naming_the_problem() {
    let model = load(DEFAULT_ARM_URDF, ModelOptions::default());
    let err = find_frame(&model, "link99").unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("'link99'") && text.contains("link7") && text.contains("base_link"),
        "{text}"
    );
    let sensor = DEFAULT_ARM_URDF.replace(
        "</robot>",
        r#"<joint name="pan" type="revolute"><parent link="link7"/><child link="sensor"/>
             <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
           <link name="sensor"/></robot>"#,
    );
    let pruned = load(
        &sensor,
        ModelOptions {
            prune_massless: true,
            ..Default::default()
        },
    );
    let err = find_frame(&pruned, "sensor").unwrap_err();
    assert!(
        matches!(err, DynamicsError::UnknownLink { pruned: true, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("pruned"), "{err}");

    let mut ws = Workspace::new(&model);
    let frame = find_frame(&model, "link7").unwrap();
    let q = vec![0.1; model.nq()];
    let err = frame_jacobian(&model, &mut ws, &q[..3], &frame, ReferenceFrame::World).unwrap_err();
    assert!(
        matches!(err, DynamicsError::Length { vector: "q", .. }),
        "{err}"
    );
    let mut bad = q.clone();
    bad[2] = f64::NAN;
    assert!(frame_placement(&model, &mut ws, &bad, &frame).is_err());
    let err = frame_jacobian(&model, &mut ws, &bad, &frame, ReferenceFrame::World).unwrap_err();
    assert!(
        matches!(
            err,
            DynamicsError::NonFinite {
                vector: "q",
                index: 2,
                ..
            }
        ),
        "{err}"
    );
    // q[2] does not move link1 (nor base_link, fixed to the world), but NaN is no coordinate:
    // every frame function names it.
    let zero = vec![0.0; model.nv()];
    for link in ["link1", "base_link"] {
        let frame = find_frame(&model, link).unwrap();
        let errors = [
            frame_placement(&model, &mut ws, &bad, &frame).map(|_| ()),
            frame_jacobian(&model, &mut ws, &bad, &frame, ReferenceFrame::Local).map(|_| ()),
            frame_classical_acceleration(
                &model,
                &mut ws,
                &bad,
                &zero,
                &zero,
                &frame,
                ReferenceFrame::LocalWorldAligned,
            )
            .map(|_| ()),
        ];
        for err in errors {
            let err = err.unwrap_err();
            assert!(
                matches!(err, DynamicsError::NonFinite { index: 2, .. }),
                "{link}: {err}"
            );
        }
    }
    // A floating base's quaternion of zero norm is named.
    let floating = load(
        DEFAULT_ARM_URDF,
        ModelOptions {
            floating_base: true,
            ..Default::default()
        },
    );
    let mut ws_floating = Workspace::new(&floating);
    let mut q_floating = vec![0.1; floating.nq()];
    q_floating[3..7].fill(0.0);
    let link7 = find_frame(&floating, "link7").unwrap();
    let err = frame_jacobian(
        &floating,
        &mut ws_floating,
        &q_floating,
        &link7,
        ReferenceFrame::World,
    )
    .unwrap_err();
    assert!(matches!(err, DynamicsError::BadQuaternion { .. }), "{err}");
    // Components so large the squared norm overflows would normalise to the identity rotation,
    // whatever the quaternion: refused too, by the frames and by the dynamics, with the norm
    // (and a tiny one's norm not underflowing to 0 in the message).
    let half = std::f64::consts::FRAC_1_SQRT_2;
    for (scale, norm) in [(1e200, "has norm 1.0"), (1e-200, "has norm 1e-200")] {
        q_floating[3..7].copy_from_slice(&[half * scale, 0.0, 0.0, half * scale]);
        let err = frame_jacobian(
            &floating,
            &mut ws_floating,
            &q_floating,
            &link7,
            ReferenceFrame::World,
        )
        .unwrap_err();
        assert!(matches!(err, DynamicsError::BadQuaternion { .. }), "{err}");
        let zero = vec![0.0; floating.nv()];
        let err = spatial_dynamics_core::algorithms::rnea::rnea(
            &floating,
            &mut ws_floating,
            &q_floating,
            &zero,
            &zero,
        )
        .unwrap_err();
        let text = err.to_string();
        let exponent = if scale > 1.0 { "e200:" } else { ":" };
        assert!(text.contains(norm) && text.contains(exponent), "{text}");
    }
    let v = vec![0.0; model.nv()];
    let err =
        frame_classical_acceleration(&model, &mut ws, &q, &v, &v, &frame, ReferenceFrame::World)
            .unwrap_err();
    assert!(err.to_string().contains("'world'"), "{err}");
    let err = frame_classical_acceleration(
        &model,
        &mut ws,
        &q,
        &v[1..],
        &v,
        &frame,
        ReferenceFrame::Local,
    )
    .unwrap_err();
    assert!(
        matches!(err, DynamicsError::Length { vector: "v", .. }),
        "{err}"
    );
    // A prismatic joint pushed to 1e308 twice overflows the placement: an error, not inf.
    let slides = "<robot name=\"s\"><link name=\"w\"/>\
        <joint name=\"a\" type=\"prismatic\"><parent link=\"w\"/><child link=\"l1\"/><axis xyz=\"1 0 0\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\
        <link name=\"l1\"><inertial><mass value=\"1\"/><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial></link>\
        <joint name=\"b\" type=\"prismatic\"><parent link=\"l1\"/><child link=\"l2\"/><axis xyz=\"1 0 0\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\
        <link name=\"l2\"/></robot>";
    let slides = load(slides, ModelOptions::default());
    let mut ws = Workspace::new(&slides);
    let l2 = find_frame(&slides, "l2").unwrap();
    let err = frame_placement(&slides, &mut ws, &[1e308, 1e308], &l2).unwrap_err();
    assert!(err.to_string().contains("'l2'"), "{err}");
    // Its centre of mass is a number: l1's (1 kg at 1e308); l2, out of range, has no mass.
    let com = center_of_mass(&slides, &mut ws, &[1e308, 1e308]).unwrap();
    assert_eq!(com.position.x, 1e308);
    // Two 1 kg bodies at 1.5e308: the mean is a number, though the sum of moments is not.
    let body = "<inertial><mass value=\"1\"/><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial>";
    let heavy_text = format!(
        "<robot name=\"h\"><link name=\"w\"/>\
         <joint name=\"a\" type=\"prismatic\"><parent link=\"w\"/><child link=\"l1\"/><axis xyz=\"1 0 0\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\
         <link name=\"l1\">{body}</link>\
         <joint name=\"b\" type=\"prismatic\"><parent link=\"l1\"/><child link=\"l2\"/><axis xyz=\"1 0 0\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\
         <link name=\"l2\">{body}</link></robot>"
    );
    let heavy = load(&heavy_text, ModelOptions::default());
    let mut ws_heavy = Workspace::new(&heavy);
    let com = center_of_mass(&heavy, &mut ws_heavy, &[1.5e308, 0.0]).unwrap();
    assert_eq!((com.mass, com.position.x), (2.0, 1.5e308));
    // l2 pushed past the largest number: refused, naming the root joint of the subtree.
    let err = center_of_mass(&heavy, &mut ws_heavy, &[1.5e308, 1.5e308]).unwrap_err();
    assert!(err.to_string().contains("centre of mass at 'a'"), "{err}");
    // 1 kg at the origin and 3 kg at 1e308: the centre of mass is at 3/4 · 1e308, though the
    // outer body's first moment, 3 kg · 1e308 m, is no number; its Jacobian, `(1, 0, 0)` for
    // the first slide and `3/4 (1, 0, 0)` for the second, the same.
    let lopsided = heavy_text.replace(
        r#"<link name="l2"><inertial><mass value="1"/>"#,
        r#"<link name="l2"><inertial><mass value="3"/>"#,
    );
    let lopsided = load(&lopsided, ModelOptions::default());
    let mut ws_lopsided = Workspace::new(&lopsided);
    let (com, j) = center_of_mass_jacobian(&lopsided, &mut ws_lopsided, &[0.0, 1e308]).unwrap();
    assert_eq!(com.mass, 4.0);
    let x = com.position.x;
    assert!((x - 0.75e308).abs() <= 1e-15 * 0.75e308, "{x:e}");
    let want = [1.0, 0.0, 0.0, 0.75, 0.0, 0.0];
    let err = j
        .iter()
        .zip(want)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(err <= 1e-15, "{j}");
    // Nothing moving has mass.
    let massless = load(
        "<robot name=\"m\"><link name=\"w\"/><joint name=\"j\" type=\"revolute\"><parent link=\"w\"/><child link=\"c\"/>\
         <axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint><link name=\"c\"/></robot>",
        ModelOptions::default(),
    );
    let err = center_of_mass(&massless, &mut Workspace::new(&massless), &[0.0]).unwrap_err();
    assert!(err.to_string().contains("mass"), "{err}");
}
