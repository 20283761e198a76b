//! Criterion benchmarks of the dynamics kernels, for development (`cargo bench`; not run in CI).
//!
//! Two models: the embedded default arm and a 32-link pendulum. Each kernel cycles through 1024
//! random states drawn before timing. For comparisons with Pinocchio use
//! `launch_scripts/bench_pinocchio.sh`, which times `spatial_dynamics bench`.

use criterion::{criterion_group, criterion_main, Criterion};
use spatial_dynamics_core::algorithms::{crba, forward_dynamics, gravity, rnea};
use spatial_dynamics_core::model::examples;
use spatial_dynamics_core::sampling::{random_q, Rng};
use spatial_dynamics_core::{
    urdf, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};
use std::hint::black_box;
use std::time::Duration;

const STATES: usize = 1024;

struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    /// Accelerations for `rnea`, efforts for forward dynamics.
    a_or_tau: Vec<f64>,
}

fn random_states(model: &Model) -> Vec<State> {
    let mut rng = Rng::new(1);
    (0..STATES)
        .map(|_| State {
            q: random_q(model, &mut rng),
            v: rng.vector(model.nv(), 1.0),
            a_or_tau: rng.vector(model.nv(), 1.0),
        })
        .collect()
}

/// Benchmarks `call` under `name`, cycling through the states.
fn bench_kernel(c: &mut Criterion, name: &str, states: &[State], mut call: impl FnMut(&State)) {
    let mut i = 0;
    c.bench_function(name, |b| {
        b.iter(|| {
            call(black_box(&states[i]));
            i = (i + 1) % states.len();
        })
    });
}

fn bench_model(c: &mut Criterion, label: &str, urdf_text: &str) {
    let model = urdf::model_from_str(urdf_text, &ModelOptions::default())
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    let states = random_states(&model);
    let mut ws = Workspace::new(&model);
    let ws = &mut ws;
    let m = &model;
    bench_kernel(c, &format!("{label}/rnea"), &states, |s| {
        black_box(rnea(m, ws, &s.q, &s.v, &s.a_or_tau).unwrap());
    });
    bench_kernel(c, &format!("{label}/crba"), &states, |s| {
        black_box(crba(m, ws, &s.q).unwrap());
    });
    for method in ForwardDynamicsMethod::ALL {
        bench_kernel(c, &format!("{label}/fd_{method}"), &states, |s| {
            let ext = Externals::none();
            black_box(forward_dynamics(m, ws, &s.q, &s.v, &s.a_or_tau, method, &ext).unwrap());
        });
    }
    bench_kernel(c, &format!("{label}/gravity"), &states, |s| {
        black_box(gravity(m, ws, &s.q).unwrap());
    });
}

fn benches(c: &mut Criterion) {
    bench_model(c, "default_arm", examples::DEFAULT_ARM_URDF);
    bench_model(c, "pendulum32", &examples::pendulum_urdf(32, 1.0, 1.0));
}

criterion_group! {
    name = algorithms;
    // Short runs: about 1.5 s per kernel, 12 kernels.
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(1));
    targets = benches
}
criterion_main!(algorithms);
