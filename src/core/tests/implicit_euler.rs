//! Implicit Euler takes only backward-Euler steps: every state it leaves solves
//! `v₁ = v₀ + h a(q₀ ⊕ h v₁, v₁)`, `q₁ = q₀ ⊕ h v₁` for the step that reached it, a whole step or,
//! where Newton's method on the whole step does not converge, two halves of it (halved again
//! where needed).

mod common;

use common::lamp;
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::sim::{Integrator, SimConfig, Simulator, State};
use spatial_dynamics_core::{urdf, Model, ModelOptions};

/// Asserts that `after` is one backward-Euler step of `h` from `before` under `config`'s forces
/// and the efforts `tau`, or else bit for bit two steps of `h/2` by a simulator of that step,
/// each checked in the same way; returns how many halvings that took. The acceleration at
/// `after` comes from one explicit-Euler step of `h` there (`v + h a(q, v)`), which applies the
/// same passive and contact forces as the step under test.
fn assert_backward_euler(
    model: &Model,
    config: &SimConfig,
    tau: &[f64],
    (before, after): (&State, &State),
    h: f64,
) -> u64 {
    let step = |integrator, dt, from: &State| {
        let config = SimConfig {
            integrator,
            dt,
            ..config.clone()
        };
        let mut sim = Simulator::new(model, config).unwrap();
        let mut to = from.clone();
        sim.step(model, &mut to, tau).unwrap();
        to
    };
    let mut q1 = vec![0.0; model.nq()];
    model.integrate(&before.q, &after.v, h, &mut q1).unwrap();
    // h a(q₁, v₁), from v₁ + h a(q₁, v₁).
    let explicit = step(Integrator::ExplicitEuler, h, after);
    let solves = q1 == after.q
        && (after.v.iter().zip(&before.v).zip(&explicit.v)).all(|((v1, v0), ve)| {
            let h_a = ve - v1;
            (v1 - v0 - h_a).abs() < 1e-9 * (1.0 + v1.abs())
        });
    if solves {
        return 0;
    }
    assert!(
        h > config.dt / 2f64.powi(10),
        "t = {}: not a backward-Euler step of {h} s",
        before.t
    );
    let mid = step(Integrator::ImplicitEuler, h / 2.0, before);
    let end = step(Integrator::ImplicitEuler, h / 2.0, &mid);
    assert_eq!(
        (&end.q, &end.v),
        (&after.q, &after.v),
        "t = {}: neither a step of {h} s nor two halves",
        before.t
    );
    1 + assert_backward_euler(model, config, tau, (before, &mid), h / 2.0)
        + assert_backward_euler(model, config, tau, (&mid, &end), h / 2.0)
}

/// Runs `steps` steps of `config` from `state` (efforts `tau(t)`), checking each; returns the
/// halvings counted by the checks, asserted equal to the simulator's own count.
fn run_checked(
    model: &Model,
    config: &SimConfig,
    mut state: State,
    steps: usize,
    tau: impl Fn(f64) -> Vec<f64>,
) -> u64 {
    let mut sim = Simulator::new(model, config.clone()).unwrap();
    let mut halvings = 0;
    for _ in 0..steps {
        let before = state.clone();
        let tau = tau(state.t);
        sim.step(model, &mut state, &tau).unwrap();
        halvings += assert_backward_euler(model, config, &tau, (&before, &state), config.dt);
    }
    assert_eq!(halvings, sim.halved_steps());
    halvings
}

#[test]
fn the_folded_arm_falls_by_backward_euler_steps_at_50_ms() {
    let model = urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap();
    let mut q0 = model.neutral();
    q0[1] = 1.5;
    q0[3] = -2.0;
    let config = SimConfig {
        integrator: Integrator::ImplicitEuler,
        dt: 0.05,
        ..Default::default()
    };
    let nv = model.nv();
    run_checked(&model, &config, State::at_rest(&model, q0), 40, |_| {
        vec![0.0; nv]
    });
}

#[test]
fn the_jumping_lamp_lands_at_5_ms_by_halved_steps() {
    // sim_lamp.sh's jump: both hinges extend hard for 0.1 s, then go limp. The penalty contacts
    // switch on and off within 5 ms steps, where Newton's method on a whole step does not
    // converge: those steps are halved.
    let (model, mut config) = lamp(&[]);
    config.integrator = Integrator::ImplicitEuler;
    config.dt = 5e-3;
    let start = State::at_rest(&model, vec![0.0, 0.0, 0.0, 0.6, -1.4]);
    let efforts = |t: f64| {
        let on = if t < 0.1 - 1e-9 { 1.0 } else { 0.0 };
        vec![0.0, 0.0, 0.0, -on, 3.0 * on]
    };
    let halvings = run_checked(&model, &config, start, 300, efforts);
    assert!(
        halvings > 0,
        "no step was halved: nothing of halving tested"
    );
}
