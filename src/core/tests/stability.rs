//! Where each integrator stops being trustworthy, with the failure detected rather than merely
//! happening. Pendulum figures: a rod of mass m = 1 kg and length L = 1 m about one end has
//! I_o = m L²/3 and, for small swings, ω² = m g (L/2) / I_o = 3g / 2L.

use spatial_dynamics_core::algorithms::{crba, gravity};
use spatial_dynamics_core::model::examples::pendulum_urdf;
use spatial_dynamics_core::sim::{Integrator, Passive, SimConfig, SimError, Simulator, State};
use spatial_dynamics_core::{urdf, Model, ModelOptions, Workspace};

const G: f64 = 9.81;

fn pendulum(n: usize, damping: Option<f64>) -> Model {
    let mut text = pendulum_urdf(n, 1.0, 1.0);
    if let Some(d) = damping {
        text = text.replace(
            "<axis xyz=\"0 1 0\"/>",
            &format!("<axis xyz=\"0 1 0\"/><dynamics damping=\"{d}\"/>"),
        );
    }
    urdf::model_from_str(&text, &ModelOptions::default()).unwrap()
}

/// Runs `steps` steps from `q0` at rest; the energies after each step, or the error.
fn run(
    model: &Model,
    integrator: Integrator,
    dt: f64,
    steps: usize,
    q0: &[f64],
    passive: Passive,
) -> (Vec<f64>, Option<SimError>) {
    let mut sim = Simulator::new(
        model,
        SimConfig {
            integrator,
            dt,
            passive,
            ..Default::default()
        },
    )
    .unwrap();
    let mut state = State::at_rest(model, q0.to_vec());
    let mut energies = vec![sim.energy(model, &state).unwrap()];
    let tau = vec![0.0; model.nv()];
    for _ in 0..steps {
        match sim.step(model, &mut state, &tau) {
            Ok(()) => energies.push(sim.energy(model, &state).unwrap()),
            Err(e) => return (energies, Some(e)),
        }
    }
    (energies, None)
}

fn omega() -> f64 {
    (3.0 * G / 2.0).sqrt()
}

#[test]
fn explicit_euler_gains_energy_at_any_step() {
    let model = pendulum(1, None);
    for dt in [1e-4, 1e-3, 1e-2] {
        let steps = (2.0 / dt) as usize;
        let (e, err) = run(
            &model,
            Integrator::ExplicitEuler,
            dt,
            steps,
            &[0.3],
            Passive::default(),
        );
        assert!(err.is_none(), "dt {dt}: {err:?}");
        // Each step multiplies the small-swing energy by about 1 + ω²h²: it only grows.
        let gained = e.last().unwrap() - e[0];
        assert!(gained > 0.0, "dt {dt}: energy changed by {gained:e}");
        let swing = e[0] + G * 0.5; // energy above the rest position
        let predicted = swing * ((1.0 + (omega() * dt).powi(2)).powf(steps as f64 / 2.0) - 1.0);
        assert!(
            gained > 0.1 * predicted,
            "dt {dt}: gained {gained:e}, small-swing estimate {predicted:e}"
        );
    }
}

#[test]
fn explicit_euler_gains_energy_on_the_double_pendulum_too() {
    let model = pendulum(2, None);
    for dt in [1e-4, 1e-3, 1e-2] {
        let (e, err) = run(
            &model,
            Integrator::ExplicitEuler,
            dt,
            (2.0 / dt) as usize,
            &[0.4, -0.3],
            Passive::default(),
        );
        assert!(err.is_none(), "dt {dt}: {err:?}");
        // Sampled once a step, the energy trend is upward: the last tenth is above the first.
        let tenth = e.len() / 10;
        let first = e[..tenth].iter().sum::<f64>() / tenth as f64;
        let last = e[e.len() - tenth..].iter().sum::<f64>() / tenth as f64;
        assert!(last > first, "dt {dt}: energy {first} → {last}");
    }
}

#[test]
fn semi_implicit_euler_is_bounded_below_omega_h_2_and_fails_above() {
    let model = pendulum(1, None);
    let rest = -G * 0.5;
    for omega_h in [0.5, 1.0, 1.5] {
        let dt = omega_h / omega();
        let (e, err) = run(
            &model,
            Integrator::SemiImplicitEuler,
            dt,
            2000,
            &[0.05],
            Passive::default(),
        );
        assert!(err.is_none(), "ωh = {omega_h}: {err:?}");
        // The symplectic map keeps a modified energy: the true one oscillates within a bounded
        // band, never drifting. Its largest value over the last quarter is no larger than over
        // the first quarter (no trend) and stays within (1 + ωh/2)/(1 − ωh/2) of the start.
        let above: Vec<f64> = e.iter().map(|x| x - rest).collect();
        let max_first = above[..500].iter().cloned().fold(0.0, f64::max);
        let max_last = above[1500..].iter().cloned().fold(0.0, f64::max);
        assert!(
            max_last <= 1.01 * max_first,
            "ωh = {omega_h}: energy trend {max_first:e} → {max_last:e}"
        );
        let band = (1.0 + omega_h / 2.0) / (1.0 - omega_h / 2.0);
        assert!(
            max_first <= 1.05 * band * above[0],
            "ωh = {omega_h}: {max_first:e} vs band {band} × {:e}",
            above[0]
        );
    }
    for omega_h in [2.2, 3.0] {
        let dt = omega_h / omega();
        let (_, err) = run(
            &model,
            Integrator::SemiImplicitEuler,
            dt,
            200,
            &[0.05],
            Passive::default(),
        );
        assert!(
            matches!(
                err,
                Some(SimError::EnergyBlowUp { .. } | SimError::NonFinite { .. })
            ),
            "ωh = {omega_h}: divergence not detected: {err:?}"
        );
    }
}

#[test]
fn semi_implicit_euler_on_the_double_pendulum_follows_its_fastest_mode() {
    // Small swings: M q̈ + K q = 0 with M = H(0) and K = ∂g/∂q at 0; the fastest normal mode
    // ω_max = √(largest eigenvalue of M⁻¹K) sets the bound ω_max h < 2.
    let model = pendulum(2, None);
    let mut ws = Workspace::new(&model);
    let m = crba(&model, &mut ws, &[0.0, 0.0]).unwrap().clone();
    let eps = 1e-6;
    let mut k = nalgebra::DMatrix::zeros(2, 2);
    for j in 0..2 {
        let mut q = [0.0, 0.0];
        q[j] = eps;
        let plus = gravity(&model, &mut ws, &q).unwrap().to_vec();
        q[j] = -eps;
        let minus = gravity(&model, &mut ws, &q).unwrap().to_vec();
        for i in 0..2 {
            k[(i, j)] = (plus[i] - minus[i]) / (2.0 * eps);
        }
    }
    let modes = (m.try_inverse().unwrap() * k).eigenvalues().unwrap();
    let omega_max = modes.iter().cloned().fold(0.0, f64::max).sqrt();
    let rest = -9.81 * (0.5 + 1.5);
    for omega_h in [0.5, 1.5] {
        let (e, err) = run(
            &model,
            Integrator::SemiImplicitEuler,
            omega_h / omega_max,
            4000,
            &[0.02, 0.02],
            Passive::default(),
        );
        assert!(err.is_none(), "ω_max h = {omega_h}: {err:?}");
        // Two modes beat against each other, so the band is looser than for one pendulum, but it
        // holds for the whole run: no growth.
        let above: Vec<f64> = e.iter().map(|x| x - rest).collect();
        let band = (1.0 + omega_h / 2.0) / (1.0 - omega_h / 2.0);
        let highest = above.iter().cloned().fold(0.0, f64::max);
        assert!(
            highest <= 2.0 * band * above[0],
            "ω_max h = {omega_h}: {highest:e} vs band {band} × {:e}",
            above[0]
        );
        let max_first = above[..1000].iter().cloned().fold(0.0, f64::max);
        let max_last = above[3000..].iter().cloned().fold(0.0, f64::max);
        assert!(
            max_last <= 1.5 * max_first,
            "ω_max h = {omega_h}: energy trend {max_first:e} → {max_last:e}"
        );
    }
    for omega_h in [2.3, 3.0] {
        let (_, err) = run(
            &model,
            Integrator::SemiImplicitEuler,
            omega_h / omega_max,
            400,
            &[0.02, 0.02],
            Passive::default(),
        );
        assert!(
            err.is_some(),
            "ω_max h = {omega_h}: divergence not detected"
        );
    }
}

#[test]
fn rk4_drift_on_a_double_pendulum_at_1khz_over_10s() {
    // Stated bound: |E(t) − E(0)| < 1e-6 of the swing energy E(0) − E_rest.
    let model = pendulum(2, None);
    let (e, err) = run(
        &model,
        Integrator::Rk4,
        1e-3,
        10_000,
        &[1.0, -0.5],
        Passive::default(),
    );
    assert!(err.is_none(), "{err:?}");
    let rest = -G * (0.5 + 1.5); // both rods hanging: centres at 0.5 m and 1.5 m below the pivot
    let swing = e[0] - rest;
    let drift = e.iter().map(|x| (x - e[0]).abs()).fold(0.0, f64::max);
    assert!(
        drift < 1e-6 * swing,
        "RK4 drift {drift:e} J for a swing energy of {swing:e} J"
    );
}

#[test]
fn stiff_damping_explicit_schemes_fail_past_the_predicted_step_implicit_does_not() {
    // With damping d the velocity obeys I_o v̇ = −d v − …: explicit updates of v are stable only
    // for h < 2 I_o / d. Here I_o = 1/3 kg·m², d = 100 N·m·s/rad: h* = 6.67 ms.
    let d = 100.0;
    let model = pendulum(1, Some(d));
    let h_star = 2.0 * (1.0 / 3.0) / d;
    let damped = Passive {
        damping: true,
        ..Default::default()
    };
    let start = [0.5];
    for integrator in [Integrator::ExplicitEuler, Integrator::SemiImplicitEuler] {
        let (_, err) = run(&model, integrator, 0.8 * h_star, 2000, &start, damped);
        assert!(err.is_none(), "{integrator} at 0.8 h*: {err:?}");
        let (_, err) = run(&model, integrator, 1.2 * h_star, 2000, &start, damped);
        assert!(
            err.is_some(),
            "{integrator} at 1.2 h*: divergence not detected"
        );
    }
    // Overdamped: it creeps back with time constant d / (m g L/2) ≈ 20 s; 3000 steps ≈ 200 s.
    let (e, err) = run(
        &model,
        Integrator::ImplicitEuler,
        10.0 * h_star,
        3000,
        &start,
        damped,
    );
    assert!(err.is_none(), "implicit Euler at 10 h*: {err:?}");
    // Heavily damped: the energy only goes down, to the rest value.
    assert!(
        e.windows(2).all(|w| w[1] <= w[0] + 1e-12),
        "implicit Euler added energy"
    );
    assert!(
        (e.last().unwrap() + G * 0.5).abs() < 1e-3,
        "not at rest: {}",
        e.last().unwrap()
    );
}

#[test]
fn a_floating_body_keeps_its_momentum_and_a_unit_quaternion() {
    // A free body in zero gravity, spinning and drifting: RK4 keeps the kinetic energy and the
    // quaternion norm (integrated on the manifold, renormalised).
    let text = r#"<robot name="b"><link name="b"><inertial><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial></link></robot>"#;
    let model = urdf::model_from_str(
        text,
        &ModelOptions {
            floating_base: true,
            gravity: Default::default(),
            ..Default::default()
        },
    )
    .unwrap();
    let mut sim = Simulator::new(
        &model,
        SimConfig {
            integrator: Integrator::Rk4,
            dt: 1e-3,
            ..Default::default()
        },
    )
    .unwrap();
    let mut state = State {
        t: 0.0,
        q: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        v: vec![0.3, -0.2, 0.1, 1.0, 2.0, 0.5],
    };
    let e0 = sim.energy(&model, &state).unwrap();
    for _ in 0..2000 {
        sim.step(&model, &mut state, &[0.0; 6]).unwrap();
    }
    let e1 = sim.energy(&model, &state).unwrap();
    assert!((e1 - e0).abs() < 1e-9 * e0, "{e0} → {e1}");
    let norm: f64 = state.q[3..7].iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!((norm - 1.0).abs() < 1e-12, "quaternion norm {norm}");
}
