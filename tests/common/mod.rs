//! Helpers shared by the integration tests: a small deterministic random generator and random
//! states for a model.
#![allow(dead_code)]

#[allow(unused_imports)]
pub use spatial_dynamics::sampling::{random_q, Rng};

/// Largest absolute difference.
pub fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Euclidean norm.
pub fn norm(a: &[f64]) -> f64 {
    a.iter().map(|x| x * x).sum::<f64>().sqrt()
}
