//! Choosing the forward-dynamics method for a model: of the methods whose answers are accurate
//! enough on this model, the one with the fewest floating-point operations per call.
//!
//! Accuracy: `aba` is the reference. The conditioning study (`benches/conditioning.py`, against
//! a 50-digit solution) found it the most accurate method on every chain measured, with an error
//! near ε even where `crba` and `rnea_columns` lose digits with cond H. A method is accurate
//! enough when, over sampled states, its `q̈` differs from `aba`'s by at most `tolerance` relative
//! to `‖q̈_aba‖∞` (1 + that, for tiny accelerations). Where `aba` does not apply (mimic joints)
//! there is no reference and the cheapest method that runs is taken.
//!
//! Cost: each method's FLOP count on this model ([`flop_table`]), not a timing, so the same
//! model gets the same method on every run and under any load (timed choices flip between
//! methods within a few per cent of each other, and a single cold call can misjudge a method
//! by orders of magnitude). On the models measured with `spatial_dynamics bench` (the 7-joint
//! arm, chains of 3 to 60 links, the mimic gripper) the FLOP counts rank the methods as their
//! times do. The methods are tried cheapest first: the
//! first that is accurate enough is chosen, and a method costing more than `aba` is never run
//! (it could not be chosen; on a 10 000-link chain one CRBA solve costs minutes). Each method
//! that ran is also timed (median of passes over the samples, within `budget`) for the summary
//! only. The sampled states are `q = q₀ ⊕ δ` (neutral configuration moved along a random
//! velocity for one second, so every joint kind stays on its manifold), random `q̇` and random
//! `τ`, drawn from a fixed seed: the accuracy check is deterministic too.

use super::{forward_dynamics, ForwardDynamicsMethod};
use crate::plan::flop_table;
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
    /// Each method that ran: its FLOPs per call, its median time per call (ns, informative only)
    /// and its largest relative difference from `aba` over the samples (`None` when `aba` cannot
    /// run on this model).
    pub measured: Vec<(ForwardDynamicsMethod, u64, f64, Option<f64>)>,
    /// Methods not run, with their FLOPs per call: more than `aba`'s, or more than a method
    /// already found accurate enough.
    pub skipped: Vec<(ForwardDynamicsMethod, u64)>,
}

impl MethodChoice {
    /// One line: the choice and the measurements behind it.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self
            .measured
            .iter()
            .map(|(m, flops, ns, diff)| match diff {
                Some(d) => format!(
                    "{m} {flops} FLOPs {:.2} µs (differs from aba by {d:.1e})",
                    ns / 1e3
                ),
                None => format!("{m} {flops} FLOPs {:.2} µs", ns / 1e3),
            })
            .collect();
        let skipped: Vec<String> = self
            .skipped
            .iter()
            .map(|(m, flops)| format!(", {m} not run ({flops} FLOPs per call)"))
            .collect();
        format!(
            "{} (measured: {}{}; the fewest FLOPs among the methods agreeing with aba)",
            self.method,
            parts.join(", "),
            skipped.concat()
        )
    }
}

/// Number of sampled states, and of timed passes over them (the median pass is kept).
const SAMPLES: usize = 16;
const PASSES: usize = 5;

/// Picks the forward-dynamics method for `model`: the one with the fewest FLOPs per call whose
/// relative difference from `aba` stays within `tolerance` over the samples (`aba` itself always
/// qualifies). The choice depends on the model and `tolerance` only; `budget` bounds the time
/// spent timing each method for the summary. Errors only if no method can run at all.
pub fn choose_method(
    model: &Model,
    tolerance: f64,
    budget: Duration,
) -> Result<MethodChoice, DynamicsError> {
    let mut ws = Workspace::new(model);
    let states = sample_states(model);
    let flops_of = |m: ForwardDynamicsMethod| {
        flop_table::kernel_flops(model, &format!("fd_{}", m.name())).map(|f| f.total())
    };
    // Cheapest first (FLOP counts tie only between identical costs: then the order of ALL).
    // A method without a count (aba on a mimic model) does not apply.
    let mut order: Vec<(ForwardDynamicsMethod, u64)> = ForwardDynamicsMethod::ALL
        .into_iter()
        .filter_map(|m| flops_of(m).map(|f| (m, f)))
        .collect();
    order.sort_by_key(|&(_, f)| f);
    let mut first_error = None;
    // aba's answers and cost, when it runs on this model.
    let reference = match order.iter().find(|(m, _)| *m == ForwardDynamicsMethod::Aba) {
        Some(&(_, aba_flops)) => match answers(model, &mut ws, &states, ForwardDynamicsMethod::Aba)
        {
            Ok(qdd) => Some((qdd, aba_flops)),
            Err(e) => {
                first_error = Some(e);
                None
            }
        },
        None => None,
    };
    let mut chosen = None;
    let mut measured = Vec::new();
    let mut skipped = Vec::new();
    for (method, flops) in order {
        let qdd = match (&reference, method) {
            (Some((r, _)), ForwardDynamicsMethod::Aba) => r.clone(),
            // aba refused the model: its error is kept.
            (None, ForwardDynamicsMethod::Aba) => continue,
            // Never chosen: a cheaper accurate method exists (aba, when it runs, is one).
            (Some((_, aba_flops)), _) if flops > *aba_flops || chosen.is_some() => {
                skipped.push((method, flops));
                continue;
            }
            (None, _) if chosen.is_some() => {
                skipped.push((method, flops));
                continue;
            }
            _ => match answers(model, &mut ws, &states, method) {
                Ok(qdd) => qdd,
                Err(e) => {
                    first_error.get_or_insert(e);
                    continue;
                }
            },
        };
        let diff = reference.as_ref().map(|(r, _)| largest_difference(&qdd, r));
        let ns = time_per_call(model, &mut ws, &states, method, budget);
        measured.push((method, flops, ns, diff));
        if chosen.is_none() && diff.is_none_or(|d| d <= tolerance) {
            chosen = Some(method);
        }
    }
    // Measured in cost order; listed with aba first, as the reference.
    measured.sort_by_key(|&(m, _, _, _)| m != ForwardDynamicsMethod::Aba);
    match chosen {
        Some(method) => Ok(MethodChoice {
            method,
            measured,
            skipped,
        }),
        None => match first_error {
            Some(e) => Err(e),
            None => Ok(MethodChoice {
                method: ForwardDynamicsMethod::Aba,
                measured,
                skipped,
            }),
        },
    }
}

/// `method`'s `q̈` on every state (the first error if it refuses one).
fn answers(
    model: &Model,
    ws: &mut Workspace,
    states: &[(Vec<f64>, Vec<f64>, Vec<f64>)],
    method: ForwardDynamicsMethod,
) -> Result<Vec<Vec<f64>>, DynamicsError> {
    let ext = Externals::none();
    states
        .iter()
        .map(|(q, v, tau)| {
            forward_dynamics(model, ws, q, v, tau, method, &ext).map(<[f64]>::to_vec)
        })
        .collect()
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
            model
                .integrate(&neutral, &step, 1.0, &mut q)
                .expect("q, the step and the output are sized from the model");
            let v = rng.vector(model.nv, 1.0);
            let tau = rng.vector(model.nv, 10.0);
            (q, v, tau)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::{pendulum_urdf, DEFAULT_ARM_URDF, MIMIC_GRIPPER_URDF};
    use crate::{urdf, ModelOptions};

    fn load(text: &str) -> Model {
        urdf::model_from_str(text, &ModelOptions::default()).unwrap()
    }

    fn flops(m: ForwardDynamicsMethod, model: &Model) -> u64 {
        flop_table::kernel_flops(model, &format!("fd_{}", m.name()))
            .unwrap()
            .total()
    }

    #[test]
    fn a_method_that_disagrees_with_aba_is_not_chosen() {
        // 3 links: crba costs fewer FLOPs than aba and agrees with it to ~1e-14, not exactly;
        // with a tolerance of 0 only aba qualifies.
        let model = load(&pendulum_urdf(3, 1.0, 1.0));
        let crba = ForwardDynamicsMethod::Crba;
        assert!(flops(crba, &model) < flops(ForwardDynamicsMethod::Aba, &model));
        let choice = choose_method(&model, 0.0, Duration::from_millis(5)).unwrap();
        let diff = |m| choice.measured.iter().find(|x| x.0 == m).and_then(|x| x.3);
        assert!(diff(crba).unwrap() > 0.0, "{choice:?}");
        assert_eq!(choice.method, ForwardDynamicsMethod::Aba, "{choice:?}");
        assert_eq!(diff(ForwardDynamicsMethod::Aba), Some(0.0));
    }

    #[test]
    fn the_cheapest_accurate_method_is_chosen() {
        // The default arm and a short chain: crba has the fewest FLOPs and agrees to ~1e-14;
        // a 30-link chain: aba has the fewest, and the others are not even run.
        for (text, want) in [
            (DEFAULT_ARM_URDF.to_string(), ForwardDynamicsMethod::Crba),
            (pendulum_urdf(3, 1.0, 1.0), ForwardDynamicsMethod::Crba),
            (pendulum_urdf(30, 1.0, 1.0), ForwardDynamicsMethod::Aba),
        ] {
            let model = load(&text);
            let cheapest = ForwardDynamicsMethod::ALL
                .into_iter()
                .min_by_key(|&m| flops(m, &model))
                .unwrap();
            assert_eq!(cheapest, want);
            let choice = choose_method(&model, 1e-9, Duration::from_millis(5)).unwrap();
            assert_eq!(choice.method, want, "{choice:?}");
            assert!(choice.measured.iter().all(|m| m.3.unwrap() < 1e-9));
            if want == ForwardDynamicsMethod::Aba {
                assert_eq!(choice.measured.len(), 1, "{choice:?}");
                assert_eq!(choice.skipped.len(), 2, "{choice:?}");
            }
        }
    }

    #[test]
    fn the_same_model_gets_the_same_method_every_time_even_under_load() {
        // The default arm, where aba and crba take within a few per cent of each other's time:
        // a timed choice flips between them from run to run. Half the runs compete with threads
        // that keep every core busy.
        let model = load(DEFAULT_ARM_URDF);
        let first = choose_method(&model, AUTO_TOLERANCE, Duration::from_millis(2))
            .unwrap()
            .method;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        for round in 0..2 {
            let burners: Vec<_> = (0..if round == 1 { cores } else { 0 })
                .map(|_| {
                    let stop = stop.clone();
                    std::thread::spawn(move || {
                        let mut x = 1.0f64;
                        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                            x = std::hint::black_box(x * 1.000_000_1 + 1e-9);
                        }
                    })
                })
                .collect();
            for _ in 0..40 {
                let choice =
                    choose_method(&model, AUTO_TOLERANCE, Duration::from_millis(2)).unwrap();
                assert_eq!(choice.method, first, "round {round}: {}", choice.summary());
            }
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
            for b in burners {
                b.join().unwrap();
            }
            stop.store(false, std::sync::atomic::Ordering::Relaxed);
        }
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
            .all(|m| m.0 != ForwardDynamicsMethod::Aba && m.3.is_none()));
        assert_ne!(choice.method, ForwardDynamicsMethod::Aba);
    }
}
