//! Ground contact: the handout's lamp rests on the plane with the static penetration a spring
//! model predicts, and jumps and lands without sinking deeper than a stated depth.

mod common;

use common::lamp;
use spatial_dynamics_core::sim::{ContactPoint, Ground, Integrator, Simulator, State};
use spatial_dynamics_core::spatial::Vector3;

const MASS: f64 = 1.2; // config/models/README.md

#[test]
fn resting_lamp_sinks_by_its_weight_over_the_springs() {
    // Hinges locked (a limp lamp would fold): a rigid body on four springs, q = [x, z, θ].
    let (model, config) = lamp(&[("hinge1", 0.3), ("hinge2", -0.6)]);
    let k = config.ground.as_ref().unwrap().stiffness;
    let mut sim = Simulator::new(&model, config).unwrap();
    let mut state = State::at_rest(&model, vec![0.0, 0.0, 0.0]);
    for _ in 0..10_000 {
        sim.step(&model, &mut state, &[0.0; 3]).unwrap();
    }
    // Σ k d_i = m g with the four corners symmetric about the foot's centre: mean depth = −z.
    let expected = -MASS * 9.81 / (4.0 * k);
    assert!(
        (state.q[1] - expected).abs() < 0.05 * expected.abs(),
        "base z {} vs {expected}",
        state.q[1]
    );
    assert!(
        state.v.iter().all(|v| v.abs() < 1e-3),
        "not at rest: {:?}",
        state.v
    );
}

#[test]
fn lamp_jumps_and_lands_within_the_stated_depth() {
    // Extend both hinges hard for 0.1 s, then go limp: the lamp leaves the ground and lands.
    // Stated bound: with k = 2e4 N/m and b = 200 N·s/m, no corner sinks deeper than 5 mm.
    let (model, config) = lamp(&[]);
    let mut sim = Simulator::new(&model, config).unwrap();
    let mut state = State::at_rest(&model, vec![0.0, 0.0, 0.0, 0.6, -1.4]);
    let push = [0.0, 0.0, 0.0, -1.0, 3.0];
    let (mut highest, mut airborne) = (0.0_f64, false);
    for step in 0..5_000 {
        let tau = if step < 500 { push } else { [0.0; 5] };
        sim.step(&model, &mut state, &tau).unwrap();
        highest = highest.max(state.q[1]);
        // Airborne: the foot's lowest corner above the ground.
        let (z, theta) = (state.q[1], state.q[2]);
        airborne |= z - 0.1 * theta.sin().abs() > 0.01;
    }
    assert!(
        airborne && highest > 0.15,
        "no jump: highest base {highest} m"
    );
    assert!(
        state.q[1].abs() < 0.005,
        "did not land: base at {} m",
        state.q[1]
    );
    assert!(
        sim.max_penetration() < 0.005,
        "sank {} m into the ground",
        sim.max_penetration()
    );
}

#[test]
fn contact_points_and_ground_numbers_are_parsed_and_checked() {
    let p: ContactPoint = "foot:0.1,-0.05,0".parse().unwrap();
    assert_eq!(
        (p.link.as_str(), p.point),
        ("foot", Vector3::new(0.1, -0.05, 0.0))
    );
    assert_eq!(p.to_string().parse::<ContactPoint>().unwrap(), p);
    for bad in ["foot", "foot:1,2", ":1,2,3", "foot:1,2,x", "foot:1,2,inf"] {
        let e = bad.parse::<ContactPoint>().unwrap_err();
        assert!(e.contains(bad) && e.contains("LINK:X,Y,Z"), "{e}");
    }
    assert!(Ground::default().check().is_ok());
    for (ground, field) in [
        (
            Ground {
                stiffness: 0.0,
                ..Ground::default()
            },
            "stiffness is 0",
        ),
        (
            Ground {
                damping: -1.0,
                ..Ground::default()
            },
            "damping is -1",
        ),
        (
            Ground {
                friction: f64::NAN,
                ..Ground::default()
            },
            "friction is NaN",
        ),
        (
            Ground {
                height: f64::INFINITY,
                ..Ground::default()
            },
            "height is inf",
        ),
    ] {
        let e = ground.check().unwrap_err();
        assert!(e.contains(field), "{e}");
    }
    // A simulator refuses a bad ground, and a point on a link the model lacks.
    let (model, config) = lamp(&[]);
    let mut bad = config.clone();
    bad.ground.as_mut().unwrap().damping = -1.0;
    assert!(Simulator::new(&model, bad)
        .err()
        .unwrap()
        .contains("damping"));
    let mut bad = config;
    bad.ground.as_mut().unwrap().points[0].link = "lid".into();
    assert!(Simulator::new(&model, bad)
        .err()
        .unwrap()
        .contains("unknown link 'lid'"));
}

#[test]
fn the_deepest_penetration_is_that_of_states_the_trajectory_passes() {
    // The lamp, hinges locked, dropped from 5 cm at 1 ms steps: Runge–Kutta stages and Newton
    // iterates reach deeper than any state the run keeps; the depth reported is the deepest of
    // the kept states the simulator evaluated (RK4: each step's start; implicit Euler: each
    // step's end), computed here from the frame placement of the foot's corners.
    use spatial_dynamics_core::algorithms::frames::{find_frame, frame_placement};
    use spatial_dynamics_core::Workspace;
    for (integrator, starts) in [(Integrator::Rk4, true), (Integrator::ImplicitEuler, false)] {
        let (model, mut config) = lamp(&[("hinge1", 0.3), ("hinge2", -0.6)]);
        config.integrator = integrator;
        config.dt = 1e-3;
        let corners: Vec<Vector3> = config
            .ground
            .as_ref()
            .unwrap()
            .points
            .iter()
            .map(|p| p.point)
            .collect();
        let mut sim = Simulator::new(&model, config).unwrap();
        let mut state = State::at_rest(&model, vec![0.0, 0.05, 0.0]);
        let mut states = vec![state.clone()];
        for _ in 0..400 {
            sim.step(&model, &mut state, &[0.0; 3]).unwrap();
            states.push(state.clone());
        }
        let kept = if starts {
            &states[..states.len() - 1]
        } else {
            &states[1..]
        };
        let foot = find_frame(&model, "foot").unwrap();
        let mut ws = Workspace::new(&model);
        let deepest = kept
            .iter()
            .map(|s| {
                let x = frame_placement(&model, &mut ws, &s.q, &foot).unwrap();
                corners
                    .iter()
                    .map(|p| -(x.trans + x.rot.tr_mul(p)).z)
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        assert!(
            deepest > 1e-4,
            "{integrator}: the lamp never touched ({deepest} m)"
        );
        assert!(
            (sim.max_penetration() - deepest).abs() <= 1e-12,
            "{integrator}: reported {} m, deepest kept state {deepest} m",
            sim.max_penetration()
        );
    }
}
