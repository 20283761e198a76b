//! The algorithms against each other and against physics: forward dynamics inverts inverse
//! dynamics for every method, `H` from n+1 RNEA calls equals CRBA, energy changes by the work
//! the joint forces do, a planar joint equals the handout's massless prismatic construction,
//! and mimic joints equal the full model projected onto the leaders.

mod common;

use common::{max_diff, norm, random_q, Rng};
use spatial_dynamics_core::algorithms::{
    crba, forward_dynamics, gravity, rnea, rnea_columns::rnea_columns,
};
use spatial_dynamics_core::model::examples::{self, pendulum_urdf};
use spatial_dynamics_core::{
    urdf, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

const TREE: &str = include_str!("models/tree.urdf");

fn load(text: &str, floating_base: bool) -> Model {
    urdf::model_from_str(
        text,
        &ModelOptions {
            floating_base,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The test tree without its world link and planar base joint: rooted at the torso.
fn tree_without_base() -> String {
    let start = TREE.find("<!-- base:").unwrap();
    let end = TREE.find("<!-- end of base -->").unwrap();
    format!("{}{}", &TREE[..start], &TREE[end..])
}

fn test_models() -> Vec<(&'static str, Model)> {
    vec![
        ("tree", load(TREE, false)),
        ("tree, floating base", load(&tree_without_base(), true)),
        (
            "tree, floating joint",
            load(
                &TREE.replace(r#"type="planar""#, r#"type="floating""#),
                false,
            ),
        ),
        ("pendulum 12", load(&pendulum_urdf(12, 0.5, 0.7), false)),
        ("default arm", load(examples::DEFAULT_ARM_URDF, false)),
        (
            "default arm, floating base",
            load(examples::DEFAULT_ARM_URDF, true),
        ),
        ("lamp", load(examples::LAMP_URDF, false)),
    ]
}

#[test]
fn forward_dynamics_inverts_inverse_dynamics() {
    for (name, model) in test_models() {
        let mut ws = Workspace::new(&model);
        let mut rng = Rng::new(10);
        for _ in 0..10 {
            let q = random_q(&model, &mut rng);
            let v = rng.vector(model.nv(), 2.0);
            let tau = rng.vector(model.nv(), 10.0);
            for method in ForwardDynamicsMethod::ALL {
                let a = forward_dynamics(&model, &mut ws, &q, &v, &tau, method, &Externals::none())
                    .unwrap()
                    .to_vec();
                let back = rnea(&model, &mut ws, &q, &v, &a).unwrap();
                let err = max_diff(back, &tau);
                assert!(
                    err < 1e-9 * (1.0 + norm(&tau)),
                    "{name}, {method}: |RNEA(FD(τ)) − τ| = {err:e}"
                );
            }
        }
    }
}

#[test]
fn mass_matrix_from_rnea_columns_equals_crba() {
    for (name, model) in test_models() {
        let mut ws = Workspace::new(&model);
        let mut rng = Rng::new(11);
        for _ in 0..5 {
            let q = random_q(&model, &mut rng);
            let v = rng.vector(model.nv(), 2.0);
            let tau = vec![0.0; model.nv()];
            rnea_columns(&model, &mut ws, &q, &v, &tau, &Externals::none()).unwrap();
            let from_columns = ws.mass_matrix().clone();
            let from_crba = crba(&model, &mut ws, &q).unwrap();
            let err = (&from_columns - from_crba).amax();
            assert!(
                err < 1e-10 * from_crba.amax(),
                "{name}: H differs by {err:e}"
            );
            assert!(
                (from_crba - from_crba.transpose()).amax() == 0.0,
                "{name}: CRBA's H is not symmetric"
            );
        }
    }
}

/// Kinetic energy `T = ½ q̇ᵀ H(q) q̇`.
fn kinetic_energy(model: &Model, ws: &mut Workspace, q: &[f64], v: &[f64]) -> f64 {
    let h = crba(model, ws, q).unwrap();
    let v = nalgebra::DVector::from_column_slice(v);
    0.5 * v.dot(&(h * &v))
}

#[test]
fn power_balance_along_a_trajectory() {
    // d/dt (T + V) = q̇ᵀ τ, where the potential's gradient is the generalized gravity, ∂V/∂q = g(q).
    // Integrate q̈ = FD(q, q̇, τ(t)) with RK4, and alongside it the work W = ∫ q̇ᵀ τ dt and
    // ΔV = ∫ q̇ᵀ g(q) dt; then T(t) − T(0) + ΔV must equal W. Run with gravity off and on.
    for (name, model) in test_models()
        .into_iter()
        .filter(|(n, _)| !n.contains("floating"))
    {
        for gravity_on in [false, true] {
            let model = if gravity_on {
                model.clone()
            } else {
                model.clone().with_gravity(Default::default()).unwrap()
            };
            let mut ws = Workspace::new(&model);
            let mut rng = Rng::new(12);
            let n = model.nv();
            let mut q = random_q(&model, &mut rng);
            let mut v = rng.vector(n, 1.0);
            let amplitude = rng.vector(n, 3.0);
            let torque = |t: f64| -> Vec<f64> {
                amplitude
                    .iter()
                    .enumerate()
                    .map(|(i, a)| a * (3.0 * t + i as f64).sin())
                    .collect()
            };
            // State y = (q, v, W, U) with Ẇ = q̇ᵀ τ and U̇ = q̇ᵀ g(q) (so V(t) − V(0) = U).
            let mut deriv = |q: &[f64], v: &[f64], t: f64| -> (Vec<f64>, Vec<f64>, f64, f64) {
                let tau = torque(t);
                let a = forward_dynamics(
                    &model,
                    &mut ws,
                    q,
                    v,
                    &tau,
                    ForwardDynamicsMethod::Aba,
                    &Externals::none(),
                )
                .unwrap()
                .to_vec();
                let g = gravity(&model, &mut ws, q).unwrap();
                let power: f64 = v.iter().zip(&tau).map(|(x, y)| x * y).sum();
                let gravity_power: f64 = v.iter().zip(g).map(|(x, y)| x * y).sum();
                (v.to_vec(), a, power, gravity_power)
            };
            let e0 = kinetic_energy(&model, &mut Workspace::new(&model), &q, &v);
            let (mut work, mut potential) = (0.0, 0.0);
            // 0.3 s at 0.25 ms: RK4's own error stays well below the tolerance.
            let dt = 2.5e-4;
            for step in 0..1200 {
                let t = step as f64 * dt;
                let axpy = |x: &[f64], d: &[f64], s: f64| -> Vec<f64> {
                    x.iter().zip(d).map(|(a, b)| a + s * b).collect()
                };
                let k1 = deriv(&q, &v, t);
                let k2 = deriv(
                    &axpy(&q, &k1.0, dt / 2.0),
                    &axpy(&v, &k1.1, dt / 2.0),
                    t + dt / 2.0,
                );
                let k3 = deriv(
                    &axpy(&q, &k2.0, dt / 2.0),
                    &axpy(&v, &k2.1, dt / 2.0),
                    t + dt / 2.0,
                );
                let k4 = deriv(&axpy(&q, &k3.0, dt), &axpy(&v, &k3.1, dt), t + dt);
                let combine = |x: &[f64], a: &[f64], b: &[f64], c: &[f64], d: &[f64]| -> Vec<f64> {
                    (0..x.len())
                        .map(|i| x[i] + dt / 6.0 * (a[i] + 2.0 * b[i] + 2.0 * c[i] + d[i]))
                        .collect()
                };
                let new_q = combine(&q, &k1.0, &k2.0, &k3.0, &k4.0);
                let new_v = combine(&v, &k1.1, &k2.1, &k3.1, &k4.1);
                work += dt / 6.0 * (k1.2 + 2.0 * k2.2 + 2.0 * k3.2 + k4.2);
                potential += dt / 6.0 * (k1.3 + 2.0 * k2.3 + 2.0 * k3.3 + k4.3);
                q = new_q;
                v = new_v;
            }
            let e1 = kinetic_energy(&model, &mut Workspace::new(&model), &q, &v);
            let imbalance = (e1 - e0) + potential - work;
            let scale = e0.abs() + e1.abs() + work.abs() + potential.abs();
            assert!(
                imbalance.abs() < 1e-8 * scale,
                "{name}, gravity {gravity_on}: ΔT + ΔV − W = {imbalance:e} (scale {scale:e})"
            );
        }
    }
}

#[test]
fn planar_joint_equals_massless_prismatic_chain() {
    // The handout models a planar base by massless prismatic x and y joints and a hinge: the
    // planar joint must give the same dynamics with q = [x, y, θ].
    let body = r#"<link name="body"><inertial><origin xyz="0.3 0.1 -0.2" rpy="0.2 0.4 0.1"/><mass value="2"/>
        <inertia ixx="0.1" ixy="0.01" ixz="0" iyy="0.2" iyz="0" izz="0.15"/></inertial></link>
        <joint name="tip_hinge" type="revolute"><parent link="body"/><child link="tip"/><origin xyz="0.5 0 0"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
        <link name="tip"><inertial><origin xyz="0.2 0 0"/><mass value="0.5"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>"#;
    let planar = format!(
        r#"<robot name="p"><link name="world"/><joint name="base" type="planar"><parent link="world"/><child link="body"/>
        <axis xyz="0 0 1"/></joint>{body}</robot>"#
    );
    let chain = format!(
        r#"<robot name="c"><link name="world"/><link name="sx"/><link name="sy"/>
        <joint name="x" type="prismatic"><parent link="world"/><child link="sx"/><axis xyz="1 0 0"/><limit lower="-9" upper="9" effort="1" velocity="1"/></joint>
        <joint name="y" type="prismatic"><parent link="sx"/><child link="sy"/><axis xyz="0 1 0"/><limit lower="-9" upper="9" effort="1" velocity="1"/></joint>
        <joint name="theta" type="continuous"><parent link="sy"/><child link="body"/><axis xyz="0 0 1"/></joint>{body}</robot>"#
    );
    let options = ModelOptions {
        gravity: nalgebra::Vector3::new(0.0, -9.81, 0.0),
        ..Default::default()
    };
    let (mp, mc) = (
        urdf::model_from_str(&planar, &options).unwrap(),
        urdf::model_from_str(&chain, &options).unwrap(),
    );
    let (mut wp, mut wc) = (Workspace::new(&mp), Workspace::new(&mc));
    let mut rng = Rng::new(13);
    for _ in 0..10 {
        let (q, v, a) = (rng.vector(4, 2.0), rng.vector(4, 2.0), rng.vector(4, 2.0));
        let tp = rnea(&mp, &mut wp, &q, &v, &a).unwrap().to_vec();
        let tc = rnea(&mc, &mut wc, &q, &v, &a).unwrap().to_vec();
        assert!(max_diff(&tp, &tc) < 1e-12, "{tp:?} vs {tc:?}");
        let ap = forward_dynamics(
            &mp,
            &mut wp,
            &q,
            &v,
            &tp,
            ForwardDynamicsMethod::Aba,
            &Externals::none(),
        )
        .unwrap();
        assert!(max_diff(ap, &a) < 1e-10);
    }
}
