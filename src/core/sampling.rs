//! Deterministic random inputs for benchmarks, tests and `method: auto`'s measurements: a
//! xorshift64* generator (no dependency, the same sequence on every machine) and configurations
//! on each joint's manifold.

use crate::model::{JointKind, Model};

/// xorshift64* (Vigna 2016): deterministic from its seed.
pub struct Rng(u64);

impl Rng {
    /// A generator whose state is the seed scrambled (never zero).
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// Uniform in [−1, 1), from the top 53 bits of the next output.
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// `n` values uniform in [−scale, scale).
    pub fn vector(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| scale * self.uniform()).collect()
    }
}

/// A configuration: angles and positions uniform in [−1.5, 1.5]; a floating joint's orientation
/// is a unit quaternion uniform on the sphere (a point uniform in the unit ball, by rejection,
/// normalised).
pub fn random_q(model: &Model, rng: &mut Rng) -> Vec<f64> {
    let mut q = rng.vector(model.nq, 1.5);
    for j in model.coordinate_joints() {
        if *j.kind == JointKind::Floating {
            let quat = &mut q[j.q_index + 3..j.q_index + 7];
            loop {
                quat.iter_mut().for_each(|x| *x = rng.uniform());
                let norm = quat.iter().map(|x| x * x).sum::<f64>().sqrt();
                if (0.1..=1.0).contains(&norm) {
                    quat.iter_mut().for_each(|x| *x /= norm);
                    break;
                }
            }
        }
    }
    q
}
