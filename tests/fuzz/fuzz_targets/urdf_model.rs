//! URDF text → model → every algorithm at a state derived from the input. A description is
//! either refused with an error that names something, or gives a model on which every
//! algorithm answers with finite numbers or an error. Never a panic, an abort or a hang.
//!
//! The input is the URDF text, optionally followed by a NUL byte and the bytes the state is
//! made from (without one, the state comes from the text's own bytes).
#![no_main]

use libfuzzer_sys::fuzz_target;
use spatial_dynamics_core::algorithms::kinematics::{body_motion, body_placements};
use spatial_dynamics_core::algorithms::{
    bias, crba, energy, forward_dynamics, gravity, rnea, rnea_with,
};
use spatial_dynamics_core::spatial::{Force, Vector3};
use spatial_dynamics_core::{
    urdf, DynamicsError, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

/// A number for the state, from one input byte: mostly moderate values, sometimes the extremes
/// that break naive code (huge, tiny, NaN, infinite).
fn number(byte: u8) -> f64 {
    match byte {
        250 => 1e200,
        251 => -1e200,
        252 => 1e-310,
        253 => f64::NAN,
        254 => f64::INFINITY,
        255 => 0.0,
        b => (b as f64 - 125.0) / 25.0,
    }
}

/// `n` numbers taken cyclically from `bytes`, starting at `offset`.
fn numbers(bytes: &[u8], offset: usize, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            number(
                bytes
                    .get((offset + i * 7) % bytes.len().max(1))
                    .copied()
                    .unwrap_or(0),
            )
        })
        .collect()
}

fn check<T: AsRef<[f64]>>(what: &str, result: Result<T, DynamicsError>) {
    match result {
        Ok(values) => assert!(
            values.as_ref().iter().all(|x| x.is_finite()),
            "{what} answered a non-finite number: {:?}",
            values.as_ref()
        ),
        Err(e) => assert!(!e.to_string().is_empty(), "{what}: empty error"),
    }
}

fn run_every_algorithm(model: &Model, data: &[u8]) {
    let mut ws = Workspace::new(model);
    let q = numbers(data, 0, model.nq());
    let v = numbers(data, 1, model.nv());
    let a = numbers(data, 2, model.nv());
    let tau = numbers(data, 3, model.nv());
    let wrenches: Vec<Force> = numbers(data, 4, 6 * model.nbodies())
        .chunks(6)
        .map(|w| {
            Force::new(
                Vector3::new(w[0], w[1], w[2]),
                Vector3::new(w[3], w[4], w[5]),
            )
        })
        .collect();
    let ext = Externals {
        wrenches: Some(&wrenches),
        ..Default::default()
    };
    check("rnea", rnea(model, &mut ws, &q, &v, &a).map(|x| x.to_vec()));
    check(
        "rnea_with",
        rnea_with(model, &mut ws, &q, &v, &a, &ext).map(|x| x.to_vec()),
    );
    check(
        "bias",
        bias(model, &mut ws, &q, &v, &ext).map(|x| x.to_vec()),
    );
    check("gravity", gravity(model, &mut ws, &q).map(|x| x.to_vec()));
    check(
        "crba",
        crba(model, &mut ws, &q).map(|h| h.as_slice().to_vec()),
    );
    check(
        "energy",
        energy(model, &mut ws, &q, &v).map(|(t, p)| vec![t, p]),
    );
    check(
        "body_placements",
        body_placements(model, &mut ws, &q).map(|x| {
            x.iter()
                .flat_map(|t| {
                    t.rot
                        .iter()
                        .chain(t.trans.iter())
                        .copied()
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        }),
    );
    check(
        "body_motion",
        body_motion(model, &mut ws, &q, &v).map(|()| {
            (0..model.nbodies())
                .flat_map(|i| {
                    let m = ws.body_velocity(i);
                    m.ang
                        .iter()
                        .chain(m.lin.iter())
                        .copied()
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        }),
    );
    for method in ForwardDynamicsMethod::ALL {
        for ext in [Externals::none(), ext] {
            check(
                method.name(),
                forward_dynamics(model, &mut ws, &q, &v, &tau, method, &ext).map(|x| x.to_vec()),
            );
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let (text, state) = match data.iter().position(|&b| b == 0) {
        Some(nul) => (&data[..nul], &data[nul + 1..]),
        None => (data, data),
    };
    let text = String::from_utf8_lossy(text);
    for options in [
        ModelOptions::default(),
        ModelOptions {
            floating_base: true,
            ignore_mimic: true,
            ..Default::default()
        },
    ] {
        match urdf::model_from_str(&text, &options) {
            Ok(model) => run_every_algorithm(&model, state),
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
});
