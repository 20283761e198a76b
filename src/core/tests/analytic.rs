//! Inverse dynamics against closed forms: the handout's particle (§3.1), a single and a double
//! pendulum, and a free-floating rigid body (handout eq. 2).

mod common;

use common::{max_diff, Rng};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use spatial_dynamics_core::algorithms::{crba, gravity, rnea, rnea_with};
use spatial_dynamics_core::model::examples::pendulum_urdf;
use spatial_dynamics_core::model::{BodySpec, JointKind, JointLimits, JointSpec, ModelBuilder};
use spatial_dynamics_core::spatial::{Force, Inertia, Transform};
use spatial_dynamics_core::{urdf, Externals, Model, ModelOptions, Workspace};

const G: f64 = 9.81;

/// The handout's particle: prismatic joint 0 along x (massless slider), prismatic joint 1 along
/// y carrying a point mass m, gravity along −y (the handout's eq. 21).
fn handout_particle(m: f64) -> Model {
    let mut b = ModelBuilder::new("particle");
    b.link(BodySpec {
        name: "world".into(),
        inertia: Inertia::zero(),
    });
    b.link(BodySpec {
        name: "slider".into(),
        inertia: Inertia::zero(),
    });
    b.link(BodySpec {
        name: "particle".into(),
        inertia: Inertia::from_com(m, &Vector3::zeros(), &Matrix3::zeros()),
    });
    for (name, parent, child, axis) in [
        ("x", "world", "slider", Vector3::x()),
        ("y", "slider", "particle", Vector3::y()),
    ] {
        b.joint(JointSpec {
            name: name.into(),
            parent: parent.into(),
            child: child.into(),
            origin: Transform::identity(),
            kind: Some(JointKind::Prismatic { axis }),
            mimic: None,
            limits: JointLimits::default(),
        });
    }
    b.build(&ModelOptions {
        gravity: Vector3::new(0.0, -G, 0.0),
        ..Default::default()
    })
    .unwrap()
}

#[test]
fn handout_particle_example() {
    let m = 2.5;
    let model = handout_particle(m);
    let mut ws = Workspace::new(&model);
    let mut rng = Rng::new(1);
    for _ in 0..10 {
        let (q, v, a) = (rng.vector(2, 2.0), rng.vector(2, 2.0), rng.vector(2, 5.0));
        let tau = rnea(&model, &mut ws, &q, &v, &a).unwrap().to_vec();
        // Eq. 30: Q0 = m q̈0, Q1 = m (q̈1 + g).
        assert!(
            (tau[0] - m * a[0]).abs() < 1e-12,
            "Q0 = {} vs {}",
            tau[0],
            m * a[0]
        );
        assert!(
            (tau[1] - m * (a[1] + G)).abs() < 1e-12,
            "Q1 = {} vs {}",
            tau[1],
            m * (a[1] + G)
        );
        // Eq. 28: f̂1 has force (m q̈0, m(q̈1+g), 0) and no moment (the mass sits at its origin);
        // f̂0 adds the moment (0, 0, −m q1 q̈0) about frame 0's origin; f̂₋₁ adds m q0 (q̈1 + g).
        let f1 = ws.joint_wrench(1);
        let force = Vector3::new(m * a[0], m * (a[1] + G), 0.0);
        assert!((f1.lin - force).norm() < 1e-12 && f1.ang.norm() < 1e-12);
        let f0 = ws.joint_wrench(0);
        assert!((f0.lin - force).norm() < 1e-12);
        assert!((f0.ang - Vector3::new(0.0, 0.0, -m * q[1] * a[0])).norm() < 1e-12);
        let f_world = ws.parent_to_body(0).transpose_apply_force(&f0);
        let moment = -m * q[1] * a[0] + m * q[0] * (a[1] + G);
        assert!((f_world.ang - Vector3::new(0.0, 0.0, moment)).norm() < 1e-12);
    }
}

#[test]
fn particle_urdf_is_the_handout_particle() {
    // config/models/particle.urdf: x, then z (vertical, gravity −z): Q = (m q̈0, m (q̈1 + g)).
    let model = urdf::model_from_str(
        spatial_dynamics_core::model::examples::PARTICLE_URDF,
        &ModelOptions::default(),
    )
    .unwrap();
    let mut ws = Workspace::new(&model);
    let mut rng = Rng::new(5);
    for _ in 0..5 {
        let (q, v, a) = (rng.vector(2, 2.0), rng.vector(2, 2.0), rng.vector(2, 5.0));
        let tau = rnea(&model, &mut ws, &q, &v, &a).unwrap();
        assert!(max_diff(tau, &[a[0], a[1] + G]) < 1e-12, "{tau:?}");
    }
}

#[test]
fn external_force_on_the_particle_is_subtracted() {
    let m = 1.5;
    let model = handout_particle(m);
    let mut ws = Workspace::new(&model);
    let push = Vector3::new(0.7, -2.0, 0.3);
    let wrenches = [Force::zero(), Force::new(Vector3::zeros(), push)];
    let ext = Externals {
        wrenches: Some(&wrenches),
        ..Default::default()
    };
    let (q, v, a) = ([0.3, -0.4], [1.0, 2.0], [0.5, -1.0]);
    let tau = rnea_with(&model, &mut ws, &q, &v, &a, &ext).unwrap();
    assert!((tau[0] - (m * a[0] - push.x)).abs() < 1e-12);
    assert!((tau[1] - (m * (a[1] + G) - push.y)).abs() < 1e-12);
}

fn pendulum(n: usize, length: f64, mass: f64) -> Model {
    urdf::model_from_str(&pendulum_urdf(n, length, mass), &ModelOptions::default()).unwrap()
}

#[test]
fn single_pendulum_closed_form() {
    // A rod of mass m, length l, pivot at one end: I_o = m l²/3, τ = I_o θ̈ + m g (l/2) sin θ.
    let (l, m) = (0.8, 1.7);
    let model = pendulum(1, l, m);
    let mut ws = Workspace::new(&model);
    let mut rng = Rng::new(2);
    for _ in 0..10 {
        let (q, v, a) = (rng.vector(1, 3.0), rng.vector(1, 3.0), rng.vector(1, 3.0));
        let expected = m * l * l / 3.0 * a[0] + m * G * l / 2.0 * q[0].sin();
        let tau = rnea(&model, &mut ws, &q, &v, &a).unwrap();
        assert!(
            (tau[0] - expected).abs() < 1e-12,
            "{} vs {expected}",
            tau[0]
        );
    }
}

#[test]
fn double_pendulum_closed_form() {
    // Two rods (m, l), com at the middle, I = m l²/12 about the hinge axis; θ2 relative.
    // H11 = I1 + I2 + m c² + m (l² + c² + 2 l c cos θ2), H12 = I2 + m (c² + l c cos θ2),
    // H22 = I2 + m c²; with h = −m l c sin θ2: C1 = h (2 θ̇1 θ̇2 + θ̇2²) + g1, C2 = −h θ̇1² + g2,
    // g1 = (m c + m l) g sin θ1 + m c g sin(θ1 + θ2), g2 = m c g sin(θ1 + θ2).
    let (l, m) = (0.6, 1.3);
    let (c, i) = (l / 2.0, m * l * l / 12.0);
    let model = pendulum(2, l, m);
    let mut ws = Workspace::new(&model);
    let mut rng = Rng::new(3);
    for _ in 0..20 {
        let (q, v, a) = (rng.vector(2, 3.0), rng.vector(2, 3.0), rng.vector(2, 3.0));
        let h11 = 2.0 * i + m * c * c + m * (l * l + c * c + 2.0 * l * c * q[1].cos());
        let h12 = i + m * (c * c + l * c * q[1].cos());
        let h22 = i + m * c * c;
        let h = -m * l * c * q[1].sin();
        let g2 = m * c * G * (q[0] + q[1]).sin();
        let g1 = (m * c + m * l) * G * q[0].sin() + g2;
        let expected = [
            h11 * a[0] + h12 * a[1] + h * (2.0 * v[0] * v[1] + v[1] * v[1]) + g1,
            h12 * a[0] + h22 * a[1] - h * v[0] * v[0] + g2,
        ];
        let tau = rnea(&model, &mut ws, &q, &v, &a).unwrap().to_vec();
        assert!(max_diff(&tau, &expected) < 1e-12, "{tau:?} vs {expected:?}");
        let grav = gravity(&model, &mut ws, &q).unwrap().to_vec();
        assert!(max_diff(&grav, &[g1, g2]) < 1e-12);
        let mass = crba(&model, &mut ws, &q).unwrap();
        assert!((mass[(0, 0)] - h11).abs() < 1e-12 && (mass[(0, 1)] - h12).abs() < 1e-12);
        assert!((mass[(1, 0)] - h12).abs() < 1e-12 && (mass[(1, 1)] - h22).abs() < 1e-12);
    }
}

#[test]
fn free_body_newton_euler() {
    // One rigid body on a floating joint, centre of mass at its origin (handout eq. 2):
    // force  = m (v̇ + ω × v − Rᵀ g)      (v̇: derivative of the body-frame velocity)
    // torque = I ω̇ + ω × I ω             (about the centre of mass, body frame)
    let urdf_text = r#"<robot name="brick"><link name="brick"><inertial><mass value="3.2"/>
        <inertia ixx="0.11" ixy="0.01" ixz="-0.02" iyy="0.23" iyz="0.015" izz="0.31"/></inertial></link></robot>"#;
    let model = urdf::model_from_str(
        urdf_text,
        &ModelOptions {
            floating_base: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((model.nq(), model.nv()), (7, 6));
    let inertia = Matrix3::new(0.11, 0.01, -0.02, 0.01, 0.23, 0.015, -0.02, 0.015, 0.31);
    let mut ws = Workspace::new(&model);
    let mut rng = Rng::new(4);
    for _ in 0..10 {
        let quat = UnitQuaternion::from_euler_angles(
            rng.uniform() * 3.0,
            rng.uniform(),
            rng.uniform() * 3.0,
        );
        let mut q = rng.vector(3, 2.0);
        q.extend([quat.i, quat.j, quat.k, quat.w]);
        let (v, a) = (rng.vector(6, 2.0), rng.vector(6, 2.0));
        let lin = Vector3::new(v[0], v[1], v[2]);
        let ang = Vector3::new(v[3], v[4], v[5]);
        let lin_dot = Vector3::new(a[0], a[1], a[2]);
        let ang_dot = Vector3::new(a[3], a[4], a[5]);
        let g_body = quat.inverse() * Vector3::new(0.0, 0.0, -G);
        let force = 3.2 * (lin_dot + ang.cross(&lin) - g_body);
        let torque = inertia * ang_dot + ang.cross(&(inertia * ang));
        let tau = rnea(&model, &mut ws, &q, &v, &a).unwrap().to_vec();
        let expected = [force.x, force.y, force.z, torque.x, torque.y, torque.z];
        assert!(max_diff(&tau, &expected) < 1e-12, "{tau:?} vs {expected:?}");
    }
}
