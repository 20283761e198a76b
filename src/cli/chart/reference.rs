//! A forward-dynamics reference for planar chains that shares nothing with our spatial
//! algorithms: the chain's closed-form Lagrangian (the equations documented at the top of
//! `benches/conditioning.py`), evaluated and solved in double-double arithmetic.
//!
//! The chain: `n` links hanging from the world, revolute joints `j1…jn` about y, link `k` a rod
//! of length 1 m along −z from its joint, centre of mass at −0.5 m, mass `m_k`, rotational
//! inertia about the centre of mass `diag(m_k/12, m_k/12, 1e-6 m_k)`; gravity `(0, 0, −g)`,
//! `g = 9.81`. In absolute angles `φ_k = θ_1 + … + θ_k` (`φ = S θ`, `S` lower-triangular ones),
//! with `tail_k = Σ_{k' ≥ k} m_k'`:
//!
//! ```text
//! a_ii = m_i/4 + tail_{i+1} + Iyy_i,   a_ij = m_J/2 + tail_{J+1} (J = max(i, j), i ≠ j)
//! Ĥ_ij = a_ij cos(φ_i − φ_j)                          (T = ½ φ̇ᵀ Ĥ φ̇)
//! c_i  = Σ_j a_ij sin(φ_i − φ_j) φ̇_j²                 (velocity products)
//! ĝ_i  = g (m_i/2 + tail_{i+1}) sin φ_i                (∂V/∂φ_i, V = Σ m_k g z_k)
//! H = Sᵀ Ĥ S,  C = Sᵀ (c + ĝ),  H θ̈ = τ − C
//! ```
//!
//! `H` and `C` are formed by suffix sums (`(Sᵀ X S)_ij = Σ_{p≥i, q≥j} X_pq`, no subtraction) and
//! the system is solved by Cholesky, all in double-double (unit round-off ≈ 5e-32). Cholesky's
//! error is bounded by the condition number of the diagonally scaled `D^-½ H D^-½`, which stays
//! small for these chains even where `cond H` is astronomically large (mass ratios), so the
//! reference keeps ≳ 25 correct digits over the charted cases (checked against 50-digit mpmath
//! in `tests/python/test_chart_reference.py`).
//!
//! [`chain_urdf`] writes the URDF our model parses: every number is printed with Rust's
//! shortest round-trip formatting, so the parsed doubles are exactly the reference's `m_k`,
//! `Iyy_k = fl(m_k / 12)` (the unit test below checks it on the parsed model).

// The loops index matrices the way the formulas do.
#![allow(clippy::needless_range_loop)]

use spatial_dynamics_core::double_double::DoubleDouble as Dd;

/// Gravity along −z (m/s²): the model's default `(0, 0, −9.81)`, the same double.
pub const G: f64 = 9.81;

/// A planar chain's inertial parameters, exactly as written into its URDF.
#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    /// Link masses `m_k` (kg), base to tip.
    pub masses: Vec<f64>,
    /// Rotational inertia about y at the centre of mass, `Iyy_k = fl(m_k / 12)` (kg·m²).
    pub iyy: Vec<f64>,
}

impl Chain {
    /// Links of the given masses; the error names the first mass that is not a positive normal
    /// double.
    pub fn new(masses: Vec<f64>) -> Result<Chain, String> {
        if masses.is_empty() {
            return Err("a chain needs at least one link".into());
        }
        if let Some((k, m)) = masses
            .iter()
            .enumerate()
            .find(|(_, m)| !(m.is_normal() && **m > 0.0 && (1e-6 * **m).is_normal()))
        {
            return Err(format!(
                "link{k}: mass {m:e} is not a positive normal number (with its 1e-6 spin inertia)"
            ));
        }
        let iyy = masses.iter().map(|m| m / 12.0).collect();
        Ok(Chain { masses, iyy })
    }

    pub fn len(&self) -> usize {
        self.masses.len()
    }
}

/// Masses `m_k = r^k`, `k = 0…n−1`, each the double obtained by repeated multiplication
/// (`m_0 = 1`, `m_k = fl(m_{k−1} r)`).
pub fn geometric_masses(n: usize, r: f64) -> Vec<f64> {
    std::iter::successors(Some(1.0), |m| Some(m * r))
        .take(n)
        .collect()
}

/// The chain's URDF: joints `j1…jn`, links `link0…link<n−1>`.
pub fn chain_urdf(chain: &Chain) -> String {
    let mut urdf = format!(
        "<?xml version=\"1.0\"?>\n<robot name=\"chain{}\">\n  <link name=\"base\"/>\n",
        chain.len()
    );
    for (k, (m, iyy)) in chain.masses.iter().zip(&chain.iyy).enumerate() {
        let parent = if k == 0 {
            "base".to_string()
        } else {
            format!("link{}", k - 1)
        };
        let z = if k == 0 { "0" } else { "-1" };
        urdf += &format!(
            "  <joint name=\"j{j}\" type=\"continuous\"><parent link=\"{parent}\"/><child link=\"link{k}\"/>\
             <origin xyz=\"0 0 {z}\"/><axis xyz=\"0 1 0\"/></joint>\n  \
             <link name=\"link{k}\"><inertial><origin xyz=\"0 0 -0.5\"/><mass value=\"{m:e}\"/>\
             <inertia ixx=\"{iyy:e}\" ixy=\"0\" ixz=\"0\" iyy=\"{iyy:e}\" iyz=\"0\" izz=\"{spin:e}\"/>\
             </inertial></link>\n",
            j = k + 1,
            spin = 1e-6 * m,
        );
    }
    urdf + "</robot>\n"
}

/// `θ̈` solving `H θ̈ = τ − C` for the chain at joint angles `q`, rates `v`, efforts `tau`
/// (relative coordinates, the model's joint order), in double-double. The error names the
/// joint where the mass matrix stops being positive definite, or a length mismatch.
pub fn forward_dynamics(
    chain: &Chain,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> Result<Vec<Dd>, String> {
    let n = chain.len();
    if q.len() != n || v.len() != n || tau.len() != n {
        return Err(format!(
            "reference: q, v and tau need {n} values each (got {}, {}, {})",
            q.len(),
            v.len(),
            tau.len()
        ));
    }
    let (h, c) = mass_matrix_and_bias(chain, q, v);
    let mut x: Vec<Dd> = tau.iter().zip(&c).map(|(t, c)| Dd::from(*t) - *c).collect();
    cholesky_solve(h, &mut x)?;
    Ok(x)
}

/// `H = Sᵀ Ĥ S` (row-major, full) and `C = Sᵀ (c + ĝ)`.
fn mass_matrix_and_bias(chain: &Chain, q: &[f64], v: &[f64]) -> (Vec<Vec<Dd>>, Vec<Dd>) {
    let n = chain.len();
    let m: Vec<Dd> = chain.masses.iter().map(|&x| Dd::from(x)).collect();
    // tail[k] = Σ_{k' ≥ k} m_k', tail[n] = 0.
    let mut tail = vec![Dd::ZERO; n + 1];
    for k in (0..n).rev() {
        tail[k] = tail[k + 1] + m[k];
    }
    let mut phi = Dd::ZERO;
    let mut phid = Dd::ZERO;
    let mut sin = Vec::with_capacity(n);
    let mut cos = Vec::with_capacity(n);
    let mut phid2 = Vec::with_capacity(n);
    for k in 0..n {
        phi = phi + Dd::from(q[k]);
        phid = phid + Dd::from(v[k]);
        let (s, c) = phi.sin_cos();
        sin.push(s);
        cos.push(c);
        phid2.push(phid * phid);
    }
    let a = |i: usize, j: usize| -> Dd {
        if i == j {
            m[i].mul_f64(0.25) + tail[i + 1] + Dd::from(chain.iyy[i])
        } else {
            let big = i.max(j);
            m[big].mul_f64(0.5) + tail[big + 1]
        }
    };
    // Ĥ, and c + ĝ in absolute angles.
    let mut hh = vec![vec![Dd::ZERO; n]; n];
    let mut bias = vec![Dd::ZERO; n];
    for i in 0..n {
        for j in 0..n {
            let aij = a(i, j);
            hh[i][j] = aij * (cos[i] * cos[j] + sin[i] * sin[j]);
            if i != j {
                bias[i] = bias[i] + aij * (sin[i] * cos[j] - cos[i] * sin[j]) * phid2[j];
            }
        }
        bias[i] = bias[i] + (m[i].mul_f64(0.5) + tail[i + 1]).mul_f64(G) * sin[i];
    }
    // Suffix sums: along each row (q ≥ j), then down each column (p ≥ i).
    for row in hh.iter_mut() {
        for j in (0..n.saturating_sub(1)).rev() {
            row[j] = row[j] + row[j + 1];
        }
    }
    for i in (0..n.saturating_sub(1)).rev() {
        for j in 0..n {
            hh[i][j] = hh[i][j] + hh[i + 1][j];
        }
    }
    for i in (0..n.saturating_sub(1)).rev() {
        bias[i] = bias[i] + bias[i + 1];
    }
    (hh, bias)
}

/// Solves `H x = b` in place (`b` becomes `x`) by `H = L Lᵀ`; `H` symmetric, lower part read.
fn cholesky_solve(mut h: Vec<Vec<Dd>>, b: &mut [Dd]) -> Result<(), String> {
    let n = b.len();
    for j in 0..n {
        let mut d = h[j][j];
        for k in 0..j {
            d = d - h[j][k] * h[j][k];
        }
        if d.hi.is_nan() || d.hi <= 0.0 {
            return Err(format!(
                "reference: the mass matrix is not positive definite at joint 'j{}' (pivot {:e})",
                j + 1,
                d.hi
            ));
        }
        let l_jj = d.sqrt();
        h[j][j] = l_jj;
        for i in j + 1..n {
            let mut s = h[i][j];
            for k in 0..j {
                s = s - h[i][k] * h[j][k];
            }
            h[i][j] = s / l_jj;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s = s - h[i][k] * b[k];
        }
        b[i] = s / h[i][i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s = s - h[k][i] * b[k];
        }
        b[i] = s / h[i][i];
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use spatial_dynamics_core::{urdf, ModelOptions};

    #[test]
    fn urdf_numbers_are_the_reference_numbers() {
        let chain = Chain::new(geometric_masses(12, 1e-7)).unwrap();
        let text = chain_urdf(&chain);
        let model = urdf::model_from_str(&text, &ModelOptions::default()).unwrap();
        assert_eq!(model.nv(), 12);
        assert_eq!(model.gravity().z, -G);
        for (k, body) in model.bodies().iter().enumerate() {
            assert_eq!(body.joint.name, format!("j{}", k + 1));
            assert_eq!(body.inertia.mass, chain.masses[k], "link{k}");
            assert_eq!(chain.iyy[k], chain.masses[k] / 12.0);
        }
        // Each printed number parses back to the same double.
        for m in &chain.masses {
            assert!(text.contains(&format!("<mass value=\"{m:e}\"/>")));
            assert_eq!(format!("{m:e}").parse::<f64>().unwrap(), *m);
            assert_eq!(format!("{:e}", m / 12.0).parse::<f64>().unwrap(), m / 12.0);
        }
    }

    #[test]
    fn one_link_pendulum_closed_form() {
        // One rod about its end: (m/4 + m/12) θ̈ = τ − m g/2 sin θ, i.e. θ̈ = 3 (τ − m g sin θ / 2) / m.
        for (m, q, v, tau) in [
            (1.0, 0.7, 2.0, 0.3),
            (2.5, -2.9, -1.0, 4.0),
            (1e-3, 1.2, 0.0, 0.0),
        ] {
            let chain = Chain::new(vec![m]).unwrap();
            let a = forward_dynamics(&chain, &[q], &[v], &[tau]).unwrap()[0];
            // In double-double: H = m/4 + fl(m/12), rhs = τ − g m/2 sin θ.
            let (s, _) = Dd::from(q).sin_cos();
            let h = Dd::from(m).mul_f64(0.25) + Dd::from(m / 12.0);
            let expected = (Dd::from(tau) - Dd::from(m).mul_f64(0.5 * G) * s) / h;
            assert!((a - expected).abs().to_f64() <= 1e-30 * expected.abs().to_f64().max(1.0));
            // And the textbook double-precision formula.
            let textbook = 3.0 * (tau - m * G * q.sin() / 2.0) / m;
            assert!(
                (a.to_f64() - textbook).abs() <= 1e-14 * textbook.abs().max(1.0),
                "{a:?} {textbook}"
            );
        }
    }

    #[test]
    fn two_link_chain_hanging_straight() {
        // At θ = 0 the textbook double pendulum of rods (length l = 1, centres at l/2) has
        // H11 = I1 + I2 + m2 l² + 2 m2 l (l/2), H12 = I2 + m2 l (l/2), H22 = I2, with
        // I_k = m_k l²/3 about the link's own joint; gravity and velocity terms vanish.
        let chain = Chain::new(vec![2.0, 3.0]).unwrap();
        let zero = [0.0, 0.0];
        let a = forward_dynamics(&chain, &zero, &zero, &zero).unwrap();
        assert!(a.iter().all(|x| x.to_f64() == 0.0));
        let (i1, i2, m2) = (2.0 / 3.0, 3.0 / 3.0, 3.0);
        let h = [[i1 + i2 + m2 + m2, i2 + m2 / 2.0], [i2 + m2 / 2.0, i2]];
        for (tau, col) in [([1.0, 0.0], 0), ([0.0, 1.0], 1)] {
            let a = forward_dynamics(&chain, &zero, &zero, &tau).unwrap();
            // H a = τ: check the product in double.
            for (row, hrow) in h.iter().enumerate() {
                let r = hrow[0] * a[0].to_f64() + hrow[1] * a[1].to_f64();
                let want = if row == col { 1.0 } else { 0.0 };
                assert!((r - want).abs() < 1e-14, "H a = {r}, want {want}");
            }
        }
    }

    #[test]
    fn bad_input_is_an_error_naming_it() {
        assert!(Chain::new(vec![1.0, 0.0]).unwrap_err().contains("link1"));
        assert!(Chain::new(vec![1.0, 1e-310]).unwrap_err().contains("link1"));
        let chain = Chain::new(geometric_masses(3, 0.5)).unwrap();
        assert!(forward_dynamics(&chain, &[0.0; 2], &[0.0; 3], &[0.0; 3]).is_err());
    }
}
