//! The simulator's divergence guard ("the integrator is creating energy"): a bound that does not
//! depend on where the potential energy's zero lies, checked every `ENERGY_CHECK_INTERVAL_S` of
//! simulated time, and stopping runs whose energy really grows. Torque-free runs without damping
//! conserve `T + V` exactly, which is the reference here.

use spatial_dynamics_core::model::examples::{pendulum_urdf, DEFAULT_ARM_URDF};
use spatial_dynamics_core::sim::{
    Integrator, SimConfig, SimError, Simulator, Stalled, State, ENERGY_CHECK_INTERVAL_S,
};
use spatial_dynamics_core::{urdf, ForwardDynamicsMethod, Model, ModelOptions};

fn load(text: &str) -> Model {
    urdf::model_from_str(text, &ModelOptions::default()).unwrap()
}

/// Runs up to `steps` torque-free steps from `q0` at rest: the state reached and the error, if any.
fn run(
    model: &Model,
    integrator: Integrator,
    dt: f64,
    steps: usize,
    q0: &[f64],
) -> (State, Option<SimError>) {
    let config = SimConfig {
        integrator,
        dt,
        ..Default::default()
    };
    let mut sim = Simulator::new(model, config).unwrap();
    let mut state = State::at_rest(model, q0.to_vec());
    let tau = vec![0.0; model.nv()];
    for _ in 0..steps {
        if let Err(e) = sim.step(model, &mut state, &tau) {
            return (state, Some(e));
        }
    }
    (state, None)
}

/// A rod pendulum (1 m, 1 kg) whose pivot is `height` metres above the world origin.
fn pendulum_at(height: f64) -> Model {
    let text = pendulum_urdf(1, 1.0, 1.0);
    let mounted = text.replacen(
        "<origin xyz=\"0 0 0\"/>",
        &format!("<origin xyz=\"0 0 {height}\"/>"),
        1,
    );
    assert!(
        height == 0.0 || text != mounted,
        "the pivot's origin was not found"
    );
    load(&mounted)
}

#[test]
fn the_guard_does_not_depend_on_where_the_potential_is_zero() {
    // ω = √(3g/2L): semi-implicit Euler is stable at ωh = 1.5 and diverges at ωh = 3. Raising or
    // lowering the pivot by a kilometre adds ±9.8 kJ to E(0) and nothing to the motion, so the
    // unstable run must stop at the same step and the stable one must not stop.
    let omega = (3.0 * 9.81 / 2.0f64).sqrt();
    let at = |height: f64, omega_h: f64| {
        let model = pendulum_at(height);
        run(
            &model,
            Integrator::SemiImplicitEuler,
            omega_h / omega,
            400,
            &[0.05],
        )
    };
    let stops: Vec<f64> = [0.0, 1000.0, -1000.0]
        .into_iter()
        .map(|height| match at(height, 3.0) {
            (_, Some(SimError::EnergyBlowUp { t, .. })) => t,
            (_, other) => {
                panic!("pivot at {height} m, ωh = 3: not stopped as creating energy: {other:?}")
            }
        })
        .collect();
    assert!(
        stops.iter().all(|&t| t == stops[0]),
        "stopped at {stops:?} s for pivots at 0, +1000, −1000 m"
    );
    for height in [0.0, 1000.0, -1000.0] {
        let (_, err) = at(height, 1.5);
        assert!(err.is_none(), "pivot at {height} m, ωh = 1.5: {err:?}");
    }
}

/// The check runs at the same states whichever way the energy is taken: from ABA's own
/// quantities (explicit and semi-implicit Euler, RK4 with `aba`) or by a kinematics pass of its
/// own (`crba`, `rnea_columns`). The unstable pendulum (ωh = 3, a step longer than the interval:
/// checked at every step) stops at the same time with every method, with the state the check
/// was at (its time is the error's) and that state's energy (by a kinematics pass, to rounding).
#[test]
fn the_check_runs_at_the_same_states_with_every_method() {
    let omega = (3.0 * 9.81 / 2.0f64).sqrt();
    let model = pendulum_at(0.0);
    for integrator in [Integrator::ExplicitEuler, Integrator::SemiImplicitEuler] {
        let mut stops = Vec::new();
        for method in ForwardDynamicsMethod::ALL {
            let config = SimConfig {
                integrator,
                method,
                dt: 3.0 / omega,
                ..Default::default()
            };
            let mut sim = Simulator::new(&model, config).unwrap();
            let mut state = State::at_rest(&model, vec![0.05]);
            let err = (0..400).find_map(|_| sim.step(&model, &mut state, &[0.0]).err());
            let Some(SimError::EnergyBlowUp { t, energy, .. }) = err else {
                panic!("{integrator} {method}: not stopped as creating energy: {err:?}");
            };
            assert_eq!(
                state.t, t,
                "{integrator} {method}: the state is not the checked one"
            );
            let e = sim.energy(&model, &state).unwrap();
            assert!(
                (e - energy).abs() <= 1e-12 * e.abs(),
                "{integrator} {method}: {energy} J, the state's {e} J"
            );
            stops.push(t);
        }
        assert!(
            stops.iter().all(|&t| t == stops[0]),
            "{integrator}: stopped at {stops:?} s"
        );
    }
}

/// The default arm upright at rest, a simulator to measure energies with, and its energy `E(0)`.
fn falling_arm() -> (Model, Vec<f64>, Simulator, f64) {
    let model = load(DEFAULT_ARM_URDF);
    let q0 = model.neutral();
    let mut sim = Simulator::new(&model, SimConfig::default()).unwrap();
    let e0 = sim
        .energy(&model, &State::at_rest(&model, q0.clone()))
        .unwrap();
    (model, q0, sim, e0)
}

#[test]
fn rk4_conserves_the_falling_arms_energy_and_passes_the_guard() {
    // The default arm released upright falls, whips and spins (joint rates past 100 rad/s).
    let (model, q0, mut sim, e0) = falling_arm();
    let (end, err) = run(&model, Integrator::Rk4, 1e-3, 5000, &q0);
    assert!(err.is_none(), "rk4: {err:?}");
    let e = sim.energy(&model, &end).unwrap();
    assert!((e - e0).abs() < 1e-2, "rk4 over 5 s: {e0} J → {e} J");
}

#[test]
fn semi_implicit_euler_creates_energy_on_the_spinning_arm_and_is_stopped() {
    // Semi-implicit Euler in velocity form is symplectic only for a constant mass matrix; on the
    // arm the velocity-product (Coriolis) terms are taken explicitly, and once links spin fast the
    // energy drifts upward (even at 0.1 ms). The stop must name a real excess: the energy it
    // reports is far above E(0), which the exact flow conserves, and is the energy of the state
    // the run stopped at (the state the step that checked it started from).
    let (model, q0, mut sim, e0) = falling_arm();
    let (end, err) = run(&model, Integrator::SemiImplicitEuler, 1e-3, 20_000, &q0);
    match err {
        Some(SimError::EnergyBlowUp {
            t, energy, bound, ..
        }) => {
            assert!(
                energy > bound && energy > 1.5 * e0,
                "{energy} J, E(0) = {e0} J"
            );
            // The guard takes the energy from forward dynamics' own quantities, the reference
            // by a kinematics pass: the same to rounding.
            let e = sim.energy(&model, &end).unwrap();
            assert!(
                (e - energy).abs() <= 1e-12 * e.abs(),
                "the reported energy {energy} J is not the state's, {e} J"
            );
            // Checked on the interval's grid of simulated time, not at every step.
            let checks = t / ENERGY_CHECK_INTERVAL_S;
            assert!((checks - checks.round()).abs() < 1e-6, "stopped at t = {t}");
        }
        other => panic!("semi-implicit Euler over 20 s of the falling arm: {other:?}"),
    }
}

#[test]
fn explicit_euler_on_the_arm_is_stopped() {
    let model = load(DEFAULT_ARM_URDF);
    let q0 = model.neutral();
    let (_, err) = run(&model, Integrator::ExplicitEuler, 1e-2, 2000, &q0);
    assert!(
        matches!(err, Some(SimError::EnergyBlowUp { .. })),
        "explicit Euler at 10 ms over 20 s: {err:?}"
    );
}

#[test]
fn work_done_from_rest_is_counted() {
    // A constant torque spins a free rotor (I = 0.1 kg m², no gravity torque about its vertical
    // axis) up from rest: after one RK4 step of 10 ms under 100 N m it has 5 J of kinetic
    // energy, all of it the command's work. The power at the step's start is zero, so the
    // budget must count the power at its end too.
    let rotor = r#"<robot name="rotor">
      <link name="base"/>
      <joint name="j1" type="continuous"><parent link="base"/><child link="a"/>
        <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/></joint>
      <link name="a"><inertial><mass value="1"/>
        <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
    </robot>"#;
    let model = load(rotor);
    for integrator in [Integrator::Rk4, Integrator::SemiImplicitEuler] {
        let config = SimConfig {
            integrator,
            dt: 0.01,
            ..Default::default()
        };
        let mut sim = Simulator::new(&model, config).unwrap();
        let mut state = State::at_rest(&model, vec![0.0]);
        for step in 0..20 {
            sim.step(&model, &mut state, &[100.0])
                .unwrap_or_else(|e| panic!("{integrator}, step {step}: {e}"));
        }
        let t = state.t;
        let expected = 0.5 * 0.1 * (1000.0 * t).powi(2);
        let e = sim.energy(&model, &state).unwrap()
            - sim
                .energy(&model, &State::at_rest(&model, vec![0.0]))
                .unwrap();
        assert!(
            (e - expected).abs() < 1e-6 * expected,
            "{integrator}: {e} J, {expected} J"
        );
    }
}

/// A pendulum started at 1e17 rad (float spacing 16 rad) cannot move: `q + v h` rounds back to
/// `q` while gravity speeds `v` up, and the energy grows without the potential changing. The stop
/// names the joint, its position and the spacing. A run that creates energy by its integrator
/// alone (explicit Euler at 10 ms on the arm, every position moving) names none.
#[test]
fn a_position_too_far_from_zero_to_move_is_named_when_the_guard_stops() {
    let model = load(&pendulum_urdf(1, 1.0, 1.0));
    let (_, err) = run(&model, Integrator::SemiImplicitEuler, 1e-3, 20_000, &[1e17]);
    let Some(err @ SimError::EnergyBlowUp { stalled, .. }) = &err else {
        panic!("1e17 rad: not stopped as creating energy: {err:?}");
    };
    let want = Stalled {
        coordinate: "joint1".into(),
        position: 1e17,
        spacing: 16.0,
    };
    assert_eq!(stalled.as_ref(), Some(&want));
    let message = err.to_string();
    assert!(
        message.contains("'joint1' is at 1e17")
            && message.contains("spacing of floating-point numbers (1.6e1)"),
        "{message}"
    );
    let arm = load(DEFAULT_ARM_URDF);
    let (_, err) = run(&arm, Integrator::ExplicitEuler, 1e-2, 2000, &arm.neutral());
    assert!(
        matches!(err, Some(SimError::EnergyBlowUp { stalled: None, .. })),
        "explicit Euler at 10 ms on the arm: {err:?}"
    );
}
