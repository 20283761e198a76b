//! Forward dynamics: the accelerations q̈ = FD(q, q̇, τ) under given torques, by each of the three
//! methods (ABA, CRBA with a factorisation, n + 1 RNEA calls), which agree to rounding. Each
//! `q̈` is checked by inverse dynamics: RNEA at it gives the torques back. A method that cannot
//! serve the model (ABA on mimic joints) says why, and the others still run.
//!
//! `cargo run -p spatial_dynamics_core --example forward_dynamics [ROBOT.urdf]`

use spatial_dynamics_core::algorithms::{forward_dynamics, rnea};
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::{
    urdf, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};
use std::error::Error;

fn main() -> Result<(), Box<dyn Error>> {
    let model: Model = match std::env::args().nth(1) {
        Some(path) => urdf::model_from_file(path.as_ref(), &ModelOptions::default())?,
        None => urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default())?,
    };
    let mut ws = Workspace::new(&model);

    let q = vec![0.0; model.nq()];
    let v = vec![0.0; model.nv()];
    let tau = vec![0.0; model.nv()]; // no torque: the arm falls under gravity
    for method in [
        ForwardDynamicsMethod::Aba,
        ForwardDynamicsMethod::Crba,
        ForwardDynamicsMethod::RneaColumns,
    ] {
        let qdd = match forward_dynamics(&model, &mut ws, &q, &v, &tau, method, &Externals::none())
        {
            Ok(qdd) => qdd.to_vec(),
            Err(e) => {
                println!("{:>13}: {e}", method.name());
                continue;
            }
        };
        let tau_back = rnea(&model, &mut ws, &q, &v, &qdd)?;
        let error = tau_back
            .iter()
            .zip(&tau)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        let shown: Vec<String> = qdd.iter().map(|x| format!("{x:+.6}")).collect();
        println!(
            "{:>13}: q̈ = [{}] rad/s²; RNEA(q, q̇, q̈) gives τ back to {error:.1e} N·m",
            method.name(),
            shown.join(", ")
        );
    }
    Ok(())
}
