//! `sin θ` and `cos θ` of the joint angles, all at once: every revolute joint takes one pair
//! per call, a large share of the joint updates every algorithm starts with, and libm's
//! `sin_cos` takes one angle per call behind a branchy reduction. Computed here without
//! branches, two angles share the SIMD registers.
//!
//! **Reduction** (Cody and Waite): `θ = k π/2 + r` with `k = round(θ · 2/π)`, so `|r| ≲ π/4`.
//! `π/2 = P₁ + P₂ + P₃`, where `P₁` and `P₂` carry 33 significant bits each: for `|θ| < 10⁵`
//! (`|k| < 2¹⁶`) the products `k P₁`, `k P₂` are exact, `θ − k P₁` is exact (Sterbenz: the two
//! are within a factor of two), and `t − k P₂` is computed with its rounding error `e`
//! (Knuth's two-sum), so that `r = y + δ` holds to about `2⁻¹⁰⁶` relative (`k P₃` is below
//! `10⁻¹⁶` and its own rounding negligible).
//!
//! **Kernels** on `|y| ≤ π/4` (`z = y²`): Taylor series, `sin y = y + y z Σⱼ₌₁⁸ (−1)ʲ zʲ⁻¹/(2j+1)!`
//! (truncation `y¹⁹/19! < 10⁻¹⁹`) and `cos y = 1 − z/2 + z² Σⱼ₌₂⁹ (−1)ʲ zʲ⁻²/(2j)!`
//! (truncation `y²⁰/20! < 10⁻²⁰`), each by Estrin's scheme; the tail `δ` enters to first order,
//! `sin r ≈ sin y + δ cos y`, `cos r ≈ cos y − δ sin y`, with `cos y ≈ 1 − z/2`, `sin y ≈ y`.
//! `1 − z/2` is summed with its rounding error recovered (`((1 − w) − z/2)`, exact), so both
//! results end in one rounded addition of a small correction to a leading term.
//!
//! **Quadrant**: `(sin θ, cos θ)` is `(s, c)`, `(c, −s)`, `(−s, −c)`, `(−c, s)` for
//! `k ≡ 0, 1, 2, 3 (mod 4)`, chosen by bit masks rather than branches (joint angles of random
//! states land in any quadrant), so that [`sin_cos_all`] runs two angles at a time.
//!
//! Outside `|θ| < 10⁵` (and for NaN or infinity) it defers to `f64::sin_cos`. Against a
//! double-double reference ([`DoubleDouble`](crate::double_double::DoubleDouble)) the error
//! stays within one unit in the last place over the test's 48 000 angles; without `δ` it
//! exceeds one.

use std::f64::consts::FRAC_2_PI;

/// `π/2 = P₁ + P₂ + P₃` (to about `10⁻³⁷`); `P₁`, `P₂` have 33 significant bits.
const PIO2: [f64; 3] = [
    1.5707963267341256,
    6.077100506303966e-11,
    2.0222662487959506e-21,
];

/// `1.5 · 2⁵²`: adding it to `|x| < 2⁵¹` rounds `x` to the nearest integer, which then sits in
/// the low bits of the sum's mantissa.
const ROUNDER: f64 = 6755399441055744.0;

/// Above this the fast reduction's `k P₁`, `k P₂` could stop being exact.
const REDUCTION_LIMIT: f64 = 1e5;

/// `(−1)ʲ/(2j+1)!` for `j = 1..=8`.
const SIN_COEFFS: [f64; 8] = [
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362880.0,
    -1.0 / 39916800.0,
    1.0 / 6227020800.0,
    -1.0 / 1307674368000.0,
    1.0 / 355687428096000.0,
];

/// `(−1)ʲ/(2j)!` for `j = 2..=9`.
const COS_COEFFS: [f64; 8] = [
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40320.0,
    -1.0 / 3628800.0,
    1.0 / 479001600.0,
    -1.0 / 87178291200.0,
    1.0 / 20922789888000.0,
    -1.0 / 6402373705728000.0,
];

/// `Σⱼ₌₀⁷ cⱼ zʲ` by Estrin's scheme: four pairs `c₂ᵢ + c₂ᵢ₊₁ z`, joined by `z²` and then `z⁴`
/// (given), three dependent multiply-adds deep where Horner's rule is seven.
#[inline(always)]
fn estrin(c: &[f64; 8], z: f64, z2: f64, z4: f64) -> f64 {
    let pair = |i: usize| c[i] + c[i + 1] * z;
    let (low, high) = (pair(0) + pair(2) * z2, pair(4) + pair(6) * z2);
    low + high * z4
}

/// `(sin θ, cos θ)`; a joint angle alone (see [`sin_cos_all`] for many).
#[inline(always)]
pub fn sin_cos(theta: f64) -> (f64, f64) {
    if theta.abs() < REDUCTION_LIMIT {
        kernel(theta)
    } else {
        theta.sin_cos()
    }
}

/// `sines[i], cosines[i] = sin θᵢ, cos θᵢ` for every angle, each exactly as [`sin_cos`] gives
/// it. When every angle is within the fast reduction's range the loop has no branch, and the
/// compiler computes two angles at a time in SIMD registers: half the time per angle of the
/// library's `sin_cos`, which is called one angle at a time.
#[inline(always)]
pub fn sin_cos_all(angles: &[f64], sines: &mut [f64], cosines: &mut [f64]) {
    let pairs = angles.iter().zip(sines).zip(cosines);
    if angles.iter().all(|x| x.abs() < REDUCTION_LIMIT) {
        for ((x, s), c) in pairs {
            (*s, *c) = kernel(*x);
        }
    } else {
        for ((x, s), c) in pairs {
            (*s, *c) = sin_cos(*x);
        }
    }
}

/// The reduction, the kernels and the quadrant, for `|θ| < 10⁵` (no branch).
#[inline(always)]
fn kernel(theta: f64) -> (f64, f64) {
    // Reduction: θ = k π/2 + y + δ.
    let shifted = theta * FRAC_2_PI + ROUNDER;
    let quadrant = shifted.to_bits() & 3;
    let k = shifted - ROUNDER;
    let t = theta - k * PIO2[0];
    let kp2 = k * PIO2[1];
    let (r, e) = two_diff(t, kp2);
    let kp3 = k * PIO2[2];
    let y = r - kp3;
    let delta = ((r - y) - kp3) + e;
    // Kernels on |y| ≤ π/4.
    let (z, hz) = (y * y, 0.5 * (y * y));
    let (z2, z4) = (z * z, (z * z) * (z * z));
    let w = 1.0 - hz; // cos y ≈ 1 − z/2
    let s = y + (y * z * estrin(&SIN_COEFFS, z, z2, z4) + delta * w);
    let c = w + (((1.0 - w) - hz) + (z2 * estrin(&COS_COEFFS, z, z2, z4) - delta * y));
    // Quadrant: swap when k is odd, negate sin for k ≡ 2, 3 and cos for k ≡ 1, 2.
    let swap = 0u64.wrapping_sub(quadrant & 1);
    let (s_bits, c_bits) = (s.to_bits(), c.to_bits());
    let sin_bits = (s_bits & !swap) | (c_bits & swap);
    let cos_bits = (c_bits & !swap) | (s_bits & swap);
    let sin_sign = (quadrant >> 1) << 63;
    let cos_sign = ((quadrant ^ (quadrant >> 1)) & 1) << 63;
    (
        f64::from_bits(sin_bits ^ sin_sign),
        f64::from_bits(cos_bits ^ cos_sign),
    )
}

/// `a − b = d + e` exactly, `d = fl(a − b)` (Knuth's two-sum on `a` and `−b`).
#[inline(always)]
fn two_diff(a: f64, b: f64) -> (f64, f64) {
    let d = a - b;
    let bb = d - a;
    (d, (a - (d - bb)) - (b + bb))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::double_double::DoubleDouble as Dd;
    use crate::sampling::Rng;

    /// Many angles at once give, bit for bit, what one angle at a time gives — whether every
    /// angle is in the fast range (the vectorised loop) or one is not (libm's for it), and
    /// the quadrant's signs come out as libm's do.
    #[test]
    fn all_at_once_equals_one_at_a_time() {
        let mut angles: Vec<f64> = (0..37).map(|i| -9.0 + 0.49 * f64::from(i)).collect();
        for large in [None, Some(3.0e5)] {
            if let Some(x) = large {
                angles[5] = x;
            }
            let (mut sines, mut cosines) = (vec![0.0; 37], vec![0.0; 37]);
            sin_cos_all(&angles, &mut sines, &mut cosines);
            for (i, &x) in angles.iter().enumerate() {
                let (s, c) = sin_cos(x);
                assert_eq!(
                    (sines[i].to_bits(), cosines[i].to_bits()),
                    (s.to_bits(), c.to_bits())
                );
                let (ls, lc) = x.sin_cos();
                assert!((s - ls).abs() <= 2e-16 && (c - lc).abs() <= 2e-16, "{x}");
            }
        }
        assert_eq!(sin_cos(3.0e5), 3.0e5f64.sin_cos());
        assert!(sin_cos(f64::NAN).0.is_nan());
    }

    /// [`sin_cos`] against the double-double one (`DoubleDouble::sin_cos`):
    /// within one unit in the last place of the true value, over joint angles in any quadrant,
    /// arguments a few units from multiples of π/2 (where the reduction cancels), tiny ones, and
    /// both sides of the fast reduction's limit. Checked to fail with the reduction's tail `δ`
    /// dropped (1.2 ulp).
    #[test]
    fn within_one_ulp_of_the_double_double_value() {
        let ulps = |got: f64, exact: Dd| {
            let v = exact.to_f64().abs();
            let ulp = f64::from_bits(v.to_bits() + 1) - v;
            (Dd::from_f64(got) - exact).abs().to_f64() / ulp
        };
        let mut rng = Rng::new(7);
        let mut angles: Vec<f64> = (0..20_000)
            .map(|k| {
                let scale = [4.0, 40.0, 2e5][k % 3];
                scale * (2.0 * rng.uniform() - 1.0)
            })
            .collect();
        for k in (-2000..=2000).filter(|&k| k != 0) {
            let near = (Dd::FRAC_PI_2.mul_f64(f64::from(k))).to_f64();
            for step in -3i64..=3 {
                angles.push(f64::from_bits((near.to_bits() as i64 + step) as u64));
            }
        }
        angles.extend([
            0.0,
            -0.0,
            1e-300,
            -1e-12,
            3e-8,
            std::f64::consts::FRAC_PI_4,
            99999.99,
            1e5,
        ]);
        let mut worst = (0.0, 0.0);
        for &x in &angles {
            let (s, c) = sin_cos(x);
            let (s_ref, c_ref) = Dd::from_f64(x).sin_cos();
            let (es, ec) = (ulps(s, s_ref), ulps(c, c_ref));
            assert!(
                es <= 1.0 && ec <= 1.0,
                "x = {x:e}: sin {es} ulp, cos {ec} ulp"
            );
            worst = (f64::max(worst.0, es), f64::max(worst.1, ec));
        }
        eprintln!("sin_cos: worst sin {} ulp, cos {} ulp", worst.0, worst.1);
    }
}
