//! Choosing the forward-dynamics method for a model from measurements: the fastest method whose
//! answers are accurate enough on this model.
//!
//! Accuracy: `aba` is the reference. The conditioning study (`benches/conditioning.py`, against
//! a 50-digit solution) found it the most accurate method on every chain measured, with an error
//! near ε even where `crba` and `rnea_columns` lose digits with cond H. A method is accurate
//! enough when, over sampled states, its `q̈` differs from `aba`'s by at most `tolerance` relative
//! to `‖q̈_aba‖∞` (1 + that, for tiny accelerations). Where `aba` does not apply (mimic joints)
//! there is no reference and the fastest method that runs is taken.
//!
//! Speed: each method runs over the same sampled states; the median of several timed passes is
//! its time per call. A method whose predicted cost — its FLOP count ([`super::flops`])
//! at the rate measured for one `aba` call — would exceed the budget over the samples is not run
//! at all (on a 10 000-link chain one CRBA solve costs minutes): it is reported as skipped. The sampled states are `q = q₀ ⊕ δ` (neutral configuration moved along a
//! random velocity for one second, so every joint kind stays on its manifold), random `q̇` and
//! random `τ`, drawn from a fixed seed.

use super::{flop_table, forward_dynamics, ForwardDynamicsMethod};
use crate::sampling::Rng;
use crate::{DynamicsError, Externals, Model, Workspace};
use std::time::{Duration, Instant};

/// The tolerance the node's `method: auto` and `bench` use: accelerations must agree with
/// `aba`'s to this, relative to the largest acceleration (plus one).
pub const AUTO_TOLERANCE: f64 = 1e-10;

/// What [`choose_method`] measured and decided.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodChoice {
    /// The method chosen.
    pub method: ForwardDynamicsMethod,
    /// Each method that ran: its median time per call (ns) and its largest relative difference
    /// from `aba` over the samples (`None` when `aba` cannot run on this model).
    pub measured: Vec<(ForwardDynamicsMethod, f64, Option<f64>)>,
    /// Methods not run because their predicted time per call (ns) exceeds the budget.
    pub skipped: Vec<(ForwardDynamicsMethod, f64)>,
}

impl MethodChoice {
    /// One line: the choice and the measurements behind it.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self
            .measured
            .iter()
            .map(|(m, ns, diff)| match diff {
                Some(d) => format!("{m} {:.2} µs (differs from aba by {d:.1e})", ns / 1e3),
                None => format!("{m} {:.2} µs", ns / 1e3),
            })
            .collect();
        let skipped: Vec<String> = self
            .skipped
            .iter()
            .map(|(m, ns)| format!(", {m} not run (predicted {:.1} ms per call)", ns / 1e6))
            .collect();
        format!(
            "{} (measured: {}{})",
            self.method,
            parts.join(", "),
            skipped.concat()
        )
    }
}

/// Number of sampled states, and of timed passes over them (the median pass is kept).
const SAMPLES: usize = 16;
const PASSES: usize = 5;

/// Measures every forward-dynamics method on `model` and picks the fastest whose relative
/// difference from `aba` stays within `tolerance` (`aba` itself always qualifies). Each method's
/// timing stops early once it has used `budget`. Errors only if no method can run at all.
pub fn choose_method(
    model: &Model,
    tolerance: f64,
    budget: Duration,
) -> Result<MethodChoice, DynamicsError> {
    let mut ws = Workspace::new(model);
    let states = sample_states(model);
    let ext = Externals::none();
    // The machine's rate, from one aba call (1 GFLOP/s if aba cannot run), predicts each
    // method's time per call from its FLOP count.
    let (q0, v0, tau0) = &states[0];
    let start = Instant::now();
    let aba_runs = forward_dynamics(
        model,
        &mut ws,
        q0,
        v0,
        tau0,
        ForwardDynamicsMethod::Aba,
        &ext,
    )
    .is_ok();
    let aba_ns = start.elapsed().as_nanos() as f64;
    let plan = ws.plan().clone();
    let flops_of = |m: ForwardDynamicsMethod| {
        flop_table::kernel_flops(model, &plan, &format!("fd_{}", m.name()))
            .map_or(1.0, |f| f.total() as f64)
    };
    let ns_per_flop = if aba_runs {
        aba_ns / flops_of(ForwardDynamicsMethod::Aba)
    } else {
        1.0
    };
    let mut skipped = Vec::new();
    // Answers of each method on every state; a method that refuses the model is left out.
    let mut answers: Vec<(ForwardDynamicsMethod, Vec<Vec<f64>>)> = Vec::new();
    let mut first_error = None;
    for method in ForwardDynamicsMethod::ALL {
        let predicted = flops_of(method) * ns_per_flop;
        if method != ForwardDynamicsMethod::Aba
            && predicted * states.len() as f64 > budget.as_nanos() as f64
        {
            skipped.push((method, predicted));
            continue;
        }
        let run: Result<Vec<Vec<f64>>, DynamicsError> = states
            .iter()
            .map(|(q, v, tau)| {
                forward_dynamics(model, &mut ws, q, v, tau, method, &ext).map(<[f64]>::to_vec)
            })
            .collect();
        match run {
            Ok(qdd) => answers.push((method, qdd)),
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    if answers.is_empty() {
        return match first_error {
            Some(e) => Err(e),
            None => Ok(MethodChoice {
                method: ForwardDynamicsMethod::Aba,
                measured: Vec::new(),
                skipped,
            }),
        };
    }
    let reference = answers
        .iter()
        .find(|(m, _)| *m == ForwardDynamicsMethod::Aba)
        .map(|(_, qdd)| qdd.clone());
    let mut measured = Vec::new();
    for (method, qdd) in &answers {
        let diff = reference.as_ref().map(|r| largest_difference(qdd, r));
        let ns = time_per_call(model, &mut ws, &states, *method, budget);
        measured.push((*method, ns, diff));
    }
    let method = measured
        .iter()
        .filter(|(_, _, diff)| diff.is_none_or(|d| d <= tolerance))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(ForwardDynamicsMethod::Aba, |(m, _, _)| *m);
    Ok(MethodChoice {
        method,
        measured,
        skipped,
    })
}

/// `max over samples of ‖a − b‖∞ / (1 + ‖b‖∞)`.
fn largest_difference(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let scale = 1.0 + y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let d = x
                .iter()
                .zip(y)
                .fold(0.0f64, |m, (p, r)| m.max((p - r).abs()));
            d / scale
        })
        .fold(0.0, f64::max)
}

/// Median over [`PASSES`] passes through the states of the time per call, in ns; passes stop
/// once `budget` is spent (at least one pass runs).
fn time_per_call(
    model: &Model,
    ws: &mut Workspace,
    states: &[(Vec<f64>, Vec<f64>, Vec<f64>)],
    method: ForwardDynamicsMethod,
    budget: Duration,
) -> f64 {
    let ext = Externals::none();
    let start = Instant::now();
    let mut passes = Vec::with_capacity(PASSES);
    while passes.len() < PASSES && (passes.is_empty() || start.elapsed() < budget) {
        let t = Instant::now();
        for (q, v, tau) in states {
            let qdd = forward_dynamics(model, ws, q, v, tau, method, &ext);
            std::hint::black_box(qdd.is_ok());
        }
        passes.push(t.elapsed().as_nanos() as f64 / states.len() as f64);
    }
    passes.sort_by(f64::total_cmp);
    passes[passes.len() / 2]
}

/// [`SAMPLES`] states `(q, q̇, τ)` from a fixed seed.
fn sample_states(model: &Model) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let mut rng = Rng::new(1);
    let neutral = model.neutral();
    (0..SAMPLES)
        .map(|_| {
            let step = rng.vector(model.nv, 1.0);
            let mut q = vec![0.0; model.nq];
            model.integrate(&neutral, &step, 1.0, &mut q);
            let v = rng.vector(model.nv, 1.0);
            let tau = rng.vector(model.nv, 10.0);
            (q, v, tau)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::{pendulum_urdf, MIMIC_GRIPPER_URDF};
    use crate::{urdf, ModelOptions};

    fn load(text: &str) -> Model {
        urdf::model_from_str(text, &ModelOptions::default()).unwrap()
    }

    #[test]
    fn a_method_that_disagrees_with_aba_is_not_chosen() {
        // 200 equal links: cond H is large and crba / rnea_columns lose digits (the conditioning
        // study measured 5e-8 and worse at n = 500); with a tolerance below what they reach,
        // only aba qualifies, whatever the timings.
        let model = load(&pendulum_urdf(200, 1.0, 1.0));
        // (A generous budget, so that no method is skipped for cost on a slow machine.)
        let choice = choose_method(&model, 1e-13, Duration::from_secs(2)).unwrap();
        let diff = |m| {
            choice
                .measured
                .iter()
                .find(|x| x.0 == m)
                .and_then(|x| x.2)
                .unwrap()
        };
        assert!(diff(ForwardDynamicsMethod::Crba) > 1e-13, "{choice:?}");
        assert_eq!(choice.method, ForwardDynamicsMethod::Aba, "{choice:?}");
        assert_eq!(diff(ForwardDynamicsMethod::Aba), 0.0);
    }

    #[test]
    fn the_fastest_accurate_method_is_chosen() {
        // A short chain: every method agrees to ~1e-14, so the choice is the fastest measured.
        let model = load(&pendulum_urdf(3, 1.0, 1.0));
        let choice = choose_method(&model, 1e-9, Duration::from_millis(20)).unwrap();
        assert_eq!(choice.measured.len(), 3);
        let fastest = choice
            .measured
            .iter()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert_eq!(choice.method, fastest.0, "{choice:?}");
        assert!(choice.measured.iter().all(|m| m.2.unwrap() < 1e-9));
    }

    #[test]
    fn methods_too_slow_for_the_budget_are_not_run() {
        // 2000 links: one CRBA solve is ~n³/6 ≈ 1.3e9 FLOPs, far beyond a 5 ms budget; aba runs.
        let model = load(&pendulum_urdf(2000, 1.0, 1.0));
        let start = Instant::now();
        let choice = choose_method(&model, 1e-10, Duration::from_millis(5)).unwrap();
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "{:?}",
            start.elapsed()
        );
        assert_eq!(choice.method, ForwardDynamicsMethod::Aba);
        let skipped: Vec<_> = choice.skipped.iter().map(|s| s.0).collect();
        assert!(skipped.contains(&ForwardDynamicsMethod::Crba), "{choice:?}");
        assert!(
            choice.summary().contains("crba not run"),
            "{}",
            choice.summary()
        );
    }

    #[test]
    fn mimic_models_choose_among_the_methods_that_run() {
        let model = load(MIMIC_GRIPPER_URDF);
        let choice = choose_method(&model, 1e-9, Duration::from_millis(5)).unwrap();
        assert!(choice
            .measured
            .iter()
            .all(|m| m.0 != ForwardDynamicsMethod::Aba && m.2.is_none()));
        assert_ne!(choice.method, ForwardDynamicsMethod::Aba);
    }
}
