//! The joint-space mass matrix H(q) by the composite-rigid-body algorithm: symmetric and positive
//! definite, its diagonal the inertia each joint sees with the others held still. The kinetic
//! energy at a velocity, `½ q̇ᵀ H q̇`, is then what `algorithms::energy` sums body by body.
//!
//! `cargo run -p spatial_dynamics_core --example mass_matrix [ROBOT.urdf]`

use nalgebra::DVector;
use spatial_dynamics_core::algorithms::{crba, energy};
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::{urdf, Model, ModelOptions, Workspace};
use std::error::Error;

fn main() -> Result<(), Box<dyn Error>> {
    let model: Model = match std::env::args().nth(1) {
        Some(path) => urdf::model_from_file(path.as_ref(), &ModelOptions::default())?,
        None => urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default())?,
    };
    let mut ws = Workspace::new(&model);

    let q = vec![0.3; model.nq()];
    let h = crba(&model, &mut ws, &q)?.clone();
    println!(
        "H(q) ({} × {}, kg·m² for revolute joints):",
        h.nrows(),
        h.ncols()
    );
    for row in h.row_iter() {
        let cells: Vec<String> = row.iter().map(|x| format!("{x:+.5}")).collect();
        println!("  [{}]", cells.join(" "));
    }

    let v = DVector::from_fn(model.nv(), |i, _| 0.5 - 0.1 * i as f64);
    let from_h = 0.5 * v.dot(&(&h * &v));
    let (kinetic, _potential) = energy(&model, &mut ws, &q, v.as_slice())?;
    let shown: Vec<String> = v.iter().map(|x| format!("{x:+.1}")).collect();
    println!("kinetic energy at q̇ = [{}]:", shown.join(", "));
    println!("  ½ q̇ᵀ H q̇ = {from_h:.12} J, algorithms::energy {kinetic:.12} J");
    Ok(())
}
