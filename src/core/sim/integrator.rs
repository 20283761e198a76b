//! The time-stepping schemes, each one function of `(q, v) → (q', v')` over a step `h` with
//! `a(q, v) = FD(q, v, τ)`:
//!
//! | name | update | order | notes |
//! |---|---|---|---|
//! | `explicit_euler` | `q' = q ⊕ h v`, `v' = v + h a(q, v)` | 1 | gains energy at any step: the cautionary baseline |
//! | `semi_implicit_euler` | `v' = v + h a(q, v)`, `q' = q ⊕ h v'` | 1 | symplectic: bounded energy error while `ω h < 2` |
//! | `rk4` | classical Runge–Kutta on `(q, v)`, stages through `⊕`, Munthe-Kaas on a floating base | 4 | order 4 on SE(3) too: stage twists carried to one tangent space by `dexp⁻¹` |
//! | `implicit_euler` | `v' = v + h a(q ⊕ h v', v')`, `q' = q ⊕ h v'`, Newton on `v'` | 1 | A-stable: for stiff damping |
//!
//! Every scheme but implicit Euler starts with `a(q, v)` at the step's start
//! ([`first_evaluation`]), the rest of the step follows ([`advance`]).
//!
//! The implicit scheme's Newton matrix `I − h ∂a/∂v − h² ∂a/∂q` is built by finite differences
//! (n extra forward-dynamics calls per iteration); each Newton step is shortened until the
//! residual falls, and a step whose iterations do not converge is taken as two half steps
//! ([`implicit_euler`]).

// The schemes index stage vectors the way the formulas do.
#![allow(clippy::needless_range_loop)]

use super::configuration::Configuration;
use super::{Evaluator, Scratch, State};
use crate::error::DynamicsError;
use crate::spatial::{Motion, Vector3};
use crate::Model;
use std::fmt;
use std::str::FromStr;

/// A time-stepping scheme.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Integrator {
    ExplicitEuler,
    SemiImplicitEuler,
    Rk4,
    ImplicitEuler,
}

impl Integrator {
    pub const ALL: [Integrator; 4] = [
        Self::ExplicitEuler,
        Self::SemiImplicitEuler,
        Self::Rk4,
        Self::ImplicitEuler,
    ];

    pub fn name(&self) -> &'static str {
        match self {
            Self::ExplicitEuler => "explicit_euler",
            Self::SemiImplicitEuler => "semi_implicit_euler",
            Self::Rk4 => "rk4",
            Self::ImplicitEuler => "implicit_euler",
        }
    }
}

impl fmt::Display for Integrator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Integrator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|i| i.name() == s).ok_or_else(|| format!("unknown integrator '{s}' (use explicit_euler, semi_implicit_euler, rk4 or implicit_euler)"))
    }
}

/// The first evaluation of a step, `a(q, v)` at the state it starts from, into `s.k_a[0]`:
/// every scheme but implicit Euler (whose first evaluation is at `q ⊕ h v`) begins with it.
/// Returns whether this scheme made it. [`advance`] finishes the step; apart, the step can
/// read what forward dynamics leaves in the workspace at the starting state (the energy
/// guard's quantities).
pub(super) fn first_evaluation(
    integrator: Integrator,
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &State,
    tau: &[f64],
) -> Result<bool, DynamicsError> {
    if integrator == Integrator::ImplicitEuler {
        return Ok(false);
    }
    eval.acceleration(model, &state.q, &state.v, tau, &mut s.k_a[0])?;
    Ok(true)
}

/// Why a step could not be taken.
#[derive(Debug)]
pub(super) enum StepError {
    /// Forward dynamics failed.
    Dynamics(DynamicsError),
    /// Implicit Euler's Newton iterations did not bring the residual down to their tolerance
    /// (`residual`: `|r| / (1 + |v'|)` at the last iterate).
    NotConverged { residual: f64 },
}

impl From<DynamicsError> for StepError {
    fn from(e: DynamicsError) -> Self {
        StepError::Dynamics(e)
    }
}

/// One step of length `h`, after its [`first_evaluation`] (`s.k_a[0] = a(q, v)`).
pub(super) fn advance(
    integrator: Integrator,
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &mut State,
    tau: &[f64],
    h: f64,
) -> Result<(), StepError> {
    match integrator {
        Integrator::ExplicitEuler => {
            s.configuration
                .integrate_in_place(&mut state.q, &state.v, h)?;
            axpy(&mut state.v, h, &s.k_a[0]);
        }
        Integrator::SemiImplicitEuler => {
            axpy(&mut state.v, h, &s.k_a[0]);
            s.configuration
                .integrate_in_place(&mut state.q, &state.v, h)?;
        }
        Integrator::Rk4 => rk4(eval, s, model, state, tau, h)?,
        Integrator::ImplicitEuler => implicit_euler(eval, s, model, state, tau, h)?,
    }
    Ok(())
}

fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

/// Classical RK4 in the Runge–Kutta–Munthe-Kaas form (Munthe-Kaas 1999; Iserles et al.,
/// "Lie-group methods", Acta Numerica 2000), of order 4 on the floating base's SE(3) too; its
/// first stage's evaluation `k_a[0]` is the step's [`first_evaluation`].
///
/// `q` moves as `q ⊕ θ`, with `θ` in the tangent space at the step's start `q`. Stage `i`
/// (`c = [0, ½, ½, 1]`) is evaluated at `(q ⊕ θ_i, v + c_i h k_a[i−1])` with `θ_1 = 0`,
/// `θ_i = c_i h u_{i−1}`, and its velocity `k_v[i]` is carried back to that tangent space:
/// `u_i = dexp⁻¹(θ_i, k_v[i])`. Then
/// `q' = q ⊕ h/6 (u_1 + 2 u_2 + 2 u_3 + u_4)`, `v' = v + h/6 (k_a1 + 2 k_a2 + 2 k_a3 + k_a4)`.
/// On Euclidean coordinates `u_i = k_v[i]` and this is the classical scheme; see
/// [`dexp_inv_in_place`] for a floating base.
fn rk4(
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &mut State,
    tau: &[f64],
    h: f64,
) -> Result<(), DynamicsError> {
    // Stage 1 is at the state itself: k_a[0] is the step's first evaluation.
    s.k_v[0].copy_from_slice(&state.v);
    for stage in 1..4 {
        let c = [0.0, 0.5, 0.5, 1.0][stage] * h;
        let (done, rest) = s.k_v.split_at_mut(stage);
        s.configuration
            .integrate(&state.q, &done[stage - 1], c, &mut s.q_stage)?;
        for ((k, v), a) in rest[0].iter_mut().zip(&state.v).zip(&s.k_a[stage - 1]) {
            *k = v + c * a;
        }
        eval.acceleration(model, &s.q_stage, &rest[0], tau, &mut s.k_a[stage])?;
        // k_v[stage] ← u_stage, with θ_stage = c u_{stage−1}.
        dexp_inv_in_place(&s.configuration, &done[stage - 1], c, &mut rest[0]);
    }
    // Every vector cut to `n` first: the loop indexes without bounds checks.
    let n = state.v.len();
    let [u0, u1, u2, u3] = s.k_v.each_ref().map(|x| &x[..n]);
    let [a0, a1, a2, a3] = s.k_a.each_ref().map(|x| &x[..n]);
    let (u, v) = (&mut s.v_stage[..n], &mut state.v[..n]);
    for i in 0..n {
        u[i] = (u0[i] + 2.0 * u1[i] + 2.0 * u2[i] + u3[i]) / 6.0;
        v[i] += h / 6.0 * (a0[i] + 2.0 * a1[i] + 2.0 * a2[i] + a3[i]);
    }
    s.configuration
        .integrate_in_place(&mut state.q, &s.v_stage, h)
}

/// `k ← dexp⁻¹(θ, k)` on each floating joint's block, with `θ = c·dir`: the rate `θ̇` at which
/// `q ⊕ θ = q·exp(θ)` moves when the base's body twist there is `k = [v; ω]` (in the base's own
/// frame at `q ⊕ θ`; `θ` in the base frame at `q`). From `exp(−θ) d/dt exp(θ) =
/// (1 − e^{−ad_θ})/ad_θ θ̇ = k`: `θ̇ = Σ_n B_n/n! (−ad_θ)ⁿ k = k + ½ [θ, k] + 1/12 [θ, [θ, k]]
/// − ad_θ⁴ k / 720 + …`, with `[θ, k] = ad_θ k` the motion cross product and `B_n` the Bernoulli
/// numbers (`B_3 = 0`). The first term omitted is `O(h⁴)` per stage, `O(h⁵)` per step: RK4 keeps
/// order 4. Euclidean coordinates are left as they are.
fn dexp_inv_in_place(configuration: &Configuration, dir: &[f64], c: f64, k: &mut [f64]) {
    let twist = |x: &[f64]| {
        Motion::new(
            Vector3::new(x[3], x[4], x[5]),
            Vector3::new(x[0], x[1], x[2]),
        )
    };
    for v_index in configuration.floating_velocities() {
        let block = v_index..v_index + 6;
        let theta = twist(&dir[block.clone()]) * c;
        let k_j = twist(&k[block.clone()]);
        let once = theta.cross_motion(&k_j);
        let u = k_j + once * 0.5 + theta.cross_motion(&once) * (1.0 / 12.0);
        k[block].copy_from_slice(&[u.lin.x, u.lin.y, u.lin.z, u.ang.x, u.ang.y, u.ang.z]);
    }
}

/// Newton iterations implicit Euler takes at most on one step before it halves it.
pub(super) const MAX_NEWTON_ITERATIONS: usize = 20;

/// How many times implicit Euler halves a step whose Newton iterations do not converge: the
/// shortest step it takes is `h / 2¹⁰`.
pub(super) const MAX_HALVINGS: u32 = 10;

/// Backward Euler, `v' = v + h a(q ⊕ h v', v')`, `q' = q ⊕ h v'`, over a step of `h`. A step
/// whose Newton iterations ([`backward_euler_step`]) do not converge is taken as two backward
/// Euler steps of `h/2` one after the other, each halved again in the same way, down to
/// `h / 2^MAX_HALVINGS`: every state it leaves solves the backward-Euler equation of the
/// (sub-)step that reached it. Past that the step is not taken ([`StepError::NotConverged`]).
/// Penalty contacts switch on and off within a step, where Newton's method on the whole step
/// can cycle; over shorter steps the contact force is smooth again.
fn implicit_euler(
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &mut State,
    tau: &[f64],
    h: f64,
) -> Result<(), StepError> {
    halving(eval, s, model, state, tau, h, 0)
}

fn halving(
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &mut State,
    tau: &[f64],
    h: f64,
    depth: u32,
) -> Result<(), StepError> {
    match backward_euler_step(eval, s, model, state, tau, h) {
        Err(StepError::NotConverged { .. }) if depth < MAX_HALVINGS => {
            s.halved += 1;
            halving(eval, s, model, state, tau, h / 2.0, depth + 1)?;
            halving(eval, s, model, state, tau, h / 2.0, depth + 1)
        }
        result => result,
    }
}

/// One backward-Euler step by Newton's method on `v'`:
/// `r(v') = v' − v − h a(q ⊕ h v', v') = 0`, `J = I − h ∂a/∂v − h² ∂a/∂q` (by differencing `r`),
/// until `|r| ≤ 10⁻¹² (1 + |v'|)`. Each Newton step `Δ = J⁻¹ r` is shortened, `v' ← v' − λ Δ`
/// with `λ = 1, ½, ¼, …, 2⁻⁸`, until `|r|` falls (Armijo's test, `|r_new| ≤ (1 − 10⁻⁴ λ) |r|`).
/// A step whose iterations do not get there in [`MAX_NEWTON_ITERATIONS`], or whose residual no
/// shortened step lowers, leaves `state` as it was ([`StepError::NotConverged`]).
fn backward_euler_step(
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &mut State,
    tau: &[f64],
    h: f64,
) -> Result<(), StepError> {
    // v' in k_v[0], a trial v' in k_v[1], a(q ⊕ h v', v') in k_a[0], the Newton step in a_probe.
    let n = state.v.len();
    s.k_v[0].copy_from_slice(&state.v);
    let mut norm = residual_at(eval, s, model, state, tau, h, 0)?;
    for iteration in 0.. {
        let scale = 1.0 + s.k_v[0].iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm <= 1e-12 * scale {
            // Evaluated at the step's end, which the step keeps.
            eval.at_trajectory_state();
            break;
        }
        let not_converged = StepError::NotConverged {
            residual: norm / scale,
        };
        if iteration == MAX_NEWTON_ITERATIONS {
            return Err(not_converged);
        }
        newton_matrix(eval, s, model, state, tau, h)?;
        solve_in_place(&mut s.jacobian, &mut s.residual);
        s.a_probe.copy_from_slice(s.residual.as_slice());
        let mut lambda = 1.0;
        loop {
            for i in 0..n {
                s.k_v[1][i] = s.k_v[0][i] - lambda * s.a_probe[i];
            }
            let trial = residual_at(eval, s, model, state, tau, h, 1)?;
            if trial <= (1.0 - 1e-4 * lambda) * norm {
                norm = trial;
                break;
            }
            if lambda < 1.0 / 256.0 {
                return Err(not_converged);
            }
            lambda *= 0.5;
        }
        s.k_v.swap(0, 1);
    }
    state.v.copy_from_slice(&s.k_v[0]);
    s.configuration
        .integrate_in_place(&mut state.q, &state.v, h)?;
    Ok(())
}

/// `|r(v')|`, `r(v') = v' − v − h a(q ⊕ h v', v')`, at `v' = s.k_v[slot]`: `r` into
/// `s.residual`, `a` into `s.k_a[0]`.
fn residual_at(
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &State,
    tau: &[f64],
    h: f64,
    slot: usize,
) -> Result<f64, DynamicsError> {
    let v_new = &s.k_v[slot];
    s.configuration
        .integrate(&state.q, v_new, h, &mut s.q_stage)?;
    eval.acceleration(model, &s.q_stage, v_new, tau, &mut s.k_a[0])?;
    let mut norm = 0.0;
    for i in 0..v_new.len() {
        s.residual[i] = v_new[i] - state.v[i] - h * s.k_a[0][i];
        norm += s.residual[i] * s.residual[i];
    }
    Ok(norm.sqrt())
}

/// `J = ∂r/∂v' = I − h ∂a/∂v − h² ∂a/∂q` at `v' = s.k_v[0]` into `s.jacobian`, column by
/// column by forward differences of `a` (`s.k_a[0]` holds `a` at `v'`).
fn newton_matrix(
    eval: &mut Evaluator,
    s: &mut Scratch,
    model: &Model,
    state: &State,
    tau: &[f64],
    h: f64,
) -> Result<(), DynamicsError> {
    let n = state.v.len();
    for j in 0..n {
        let at = s.k_v[0][j];
        s.k_v[0][j] = at + 1e-7 * (1.0 + at.abs());
        let eps = s.k_v[0][j] - at;
        let probed = s
            .configuration
            .integrate(&state.q, &s.k_v[0], h, &mut s.q_probe)
            .and_then(|()| eval.acceleration(model, &s.q_probe, &s.k_v[0], tau, &mut s.a_probe));
        s.k_v[0][j] = at;
        probed?;
        for i in 0..n {
            s.jacobian[(i, j)] =
                if i == j { 1.0 } else { 0.0 } - h * (s.a_probe[i] - s.k_a[0][i]) / eps;
        }
    }
    Ok(())
}

/// Solves `A x = b` in place by Gaussian elimination with partial pivoting (`b` becomes `x`).
fn solve_in_place(a: &mut nalgebra::DMatrix<f64>, b: &mut nalgebra::DVector<f64>) {
    let n = b.len();
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&i, &j| a[(i, col)].abs().total_cmp(&a[(j, col)].abs()))
            .unwrap_or(col);
        if pivot != col {
            a.swap_rows(pivot, col);
            b.swap_rows(pivot, col);
        }
        let d = a[(col, col)];
        for row in col + 1..n {
            let f = a[(row, col)] / d;
            for k in col..n {
                a[(row, k)] -= f * a[(col, k)];
            }
            b[row] -= f * b[col];
        }
    }
    for row in (0..n).rev() {
        let mut s = b[row];
        for k in row + 1..n {
            s -= a[(row, k)] * b[k];
        }
        b[row] = s / a[(row, row)];
    }
}
