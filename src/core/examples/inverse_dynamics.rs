//! Inverse dynamics: the joint torques τ = RNEA(q, q̇, q̈) that produce a motion, and the gravity
//! torques g(q) that hold a pose.
//!
//! `cargo run -p spatial_dynamics_core --example inverse_dynamics [ROBOT.urdf]`
//! (no argument: the embedded 7-DOF default arm).

use spatial_dynamics_core::algorithms::{gravity, rnea};
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::{urdf, Model, ModelOptions, Workspace};
use std::error::Error;

fn main() -> Result<(), Box<dyn Error>> {
    let model: Model = match std::env::args().nth(1) {
        Some(path) => urdf::model_from_file(path.as_ref(), &ModelOptions::default())?,
        None => urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default())?,
    };
    // Scratch for every algorithm, sized once: no call below allocates.
    let mut ws = Workspace::new(&model);

    let q: Vec<f64> = (0..model.nq()).map(|i| 0.1 * i as f64).collect();
    let v = vec![0.5; model.nv()];
    let a = vec![1.0; model.nv()];

    let tau = rnea(&model, &mut ws, &q, &v, &a)?.to_vec();
    let g = gravity(&model, &mut ws, &q)?.to_vec();
    for (joint, (t, g)) in model.coordinate_joints().zip(tau.iter().zip(&g)) {
        println!("{:>12}  τ = {t:+.6} N·m   g = {g:+.6} N·m", joint.name);
    }
    Ok(())
}
