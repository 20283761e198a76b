//! Helpers shared by the integration tests: a small deterministic random generator and random
//! states for a model.
#![allow(dead_code)]

use spatial_dynamics::model::JointKind;
use spatial_dynamics::Model;

/// xorshift64*: deterministic, no dependency.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [-1, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    pub fn vector(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| scale * self.uniform()).collect()
    }
}

/// A random configuration: angles and positions in [-1.5, 1.5], unit quaternions.
pub fn random_q(model: &Model, rng: &mut Rng) -> Vec<f64> {
    let mut q = rng.vector(model.nq, 1.5);
    for j in model.coordinate_joints() {
        if *j.kind == JointKind::Floating {
            let quat = &mut q[j.q_index + 3..j.q_index + 7];
            let norm = quat.iter().map(|x| x * x).sum::<f64>().sqrt();
            quat.iter_mut().for_each(|x| *x /= norm);
        }
    }
    q
}

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
