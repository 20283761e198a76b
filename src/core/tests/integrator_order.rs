//! The convergence order of RK4 on a floating base's pose. A free body's stage twists live in
//! different tangent spaces of SE(3); combining them as they are is only of order 2 for the pose,
//! the Munthe-Kaas form (stages carried back by `dexp⁻¹`) is of order 4. Measured as the error
//! of the base pose at `T` against a run with the step `h/64` (16 times finer than the finest
//! measured), at `h`, `h/2`, `h/4`:
//! `log2(e(h) / e(h/2))` is the order. The step stays free of allocations on a floating base.

mod common;

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

use spatial_dynamics_core::sim::{Integrator, SimConfig, Simulator, State};
use spatial_dynamics_core::spatial::Vector3;
use spatial_dynamics_core::{urdf, Model, ModelOptions};

use nalgebra::{Quaternion, UnitQuaternion};

const T: f64 = 1.0;

/// A tumbling box (three different principal moments, centre of mass off the joint origin),
/// alone or carrying a swinging arm on a revolute joint.
fn model(with_arm: bool, gravity: Vector3) -> Model {
    let arm = if with_arm {
        r#"<link name="arm"><inertial><origin xyz="0.2 0 0"/><mass value="0.7"/><inertia ixx="0.002" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.011"/></inertial></link>
        <joint name="shoulder" type="continuous"><parent link="base"/><child link="arm"/><origin xyz="0.1 0.05 0" rpy="0.3 0 0"/><axis xyz="0 0 1"/></joint>"#
    } else {
        ""
    };
    let text = format!(
        r#"<robot name="tumbler"><link name="base"><inertial><origin xyz="0.05 -0.02 0.03" rpy="0.2 0.1 0"/><mass value="2"/><inertia ixx="0.05" ixy="0" ixz="0" iyy="0.12" iyz="0" izz="0.16"/></inertial></link>{arm}</robot>"#
    );
    urdf::model_from_str(
        &text,
        &ModelOptions {
            floating_base: true,
            gravity,
            ..Default::default()
        },
    )
    .unwrap()
}

fn rk4(model: &Model, h: f64) -> Simulator {
    let config = SimConfig {
        integrator: Integrator::Rk4,
        dt: h,
        ..Default::default()
    };
    Simulator::new(model, config).unwrap()
}

/// A spinning, drifting start.
fn start(model: &Model) -> State {
    let mut q = model.neutral();
    q[..3].copy_from_slice(&[0.1, -0.2, 1.0]);
    let mut v = vec![0.0; model.nv()];
    // [v; ω] of the base in its own frame: a fast tumble about all three axes (the middle
    // axis too, which is unstable) and a drift; the arm, if any, swings.
    v[..6].copy_from_slice(&[0.4, -0.3, 0.2, 1.5, 3.0, -2.0]);
    if v.len() > 6 {
        v[6] = 2.0;
    }
    State { t: 0.0, q, v }
}

/// The base pose `(p, R)` at `T` after `T/h` RK4 steps from [`start`].
fn base_pose_at_t(model: &Model, h: f64) -> (Vector3, UnitQuaternion<f64>) {
    let mut sim = rk4(model, h);
    let mut state = start(model);
    let tau = vec![0.0; model.nv()];
    let steps = (T / h).round() as usize;
    for _ in 0..steps {
        sim.step(model, &mut state, &tau).unwrap();
    }
    let p = Vector3::new(state.q[0], state.q[1], state.q[2]);
    let r = UnitQuaternion::from_quaternion(Quaternion::new(
        state.q[6], state.q[3], state.q[4], state.q[5],
    ));
    (p, r)
}

/// Position error plus rotation angle (m + rad: the body is ~0.3 m across).
fn pose_error(a: &(Vector3, UnitQuaternion<f64>), b: &(Vector3, UnitQuaternion<f64>)) -> f64 {
    (a.0 - b.0).norm() + a.1.angle_to(&b.1)
}

/// The observed orders between `h`, `h/2` and `h/4`, and the errors.
fn orders(model: &Model, h: f64) -> ([f64; 2], [f64; 3]) {
    let reference = base_pose_at_t(model, h / 64.0);
    let e = [1.0, 2.0, 4.0].map(|d| pose_error(&base_pose_at_t(model, h / d), &reference));
    ([(e[0] / e[1]).log2(), (e[1] / e[2]).log2()], e)
}

fn assert_fourth_order(model: &Model) {
    let (slopes, e) = orders(model, 0.05);
    // The errors must stay well above rounding (~1e-14) for the slopes to mean anything.
    assert!(e[2] > 1e-11, "errors {e:?} too small to measure an order");
    for s in slopes {
        assert!(
            s > 3.5,
            "base pose converges with order {slopes:?} (errors {e:?}), not 4"
        );
    }
}

#[test]
fn rk4_is_fourth_order_for_a_tumbling_free_body() {
    assert_fourth_order(&model(false, Vector3::zeros()));
}

#[test]
fn rk4_is_fourth_order_for_a_floating_arm_under_gravity() {
    assert_fourth_order(&model(true, Vector3::new(0.0, 0.0, -9.81)));
}

#[test]
fn rk4_on_a_floating_arm_allocates_nothing() {
    let model = model(true, Vector3::new(0.0, 0.0, -9.81));
    let mut sim = rk4(&model, 1e-3);
    let mut state = start(&model);
    let tau = vec![0.0; model.nv()];
    sim.step(&model, &mut state, &tau).unwrap();
    let count = common::allocations_during(|| {
        for _ in 0..10 {
            sim.step(&model, &mut state, &tau).unwrap();
        }
    });
    assert_eq!(count, 0, "{count} allocations in 10 RK4 steps");
}
