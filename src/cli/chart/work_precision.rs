//! Chart 3: work–precision of the integrators of [`spatial_dynamics_core::sim`].
//!
//! Two torque-free problems under gravity, from rest at a non-trivial configuration, integrated
//! to `T = 1 s` with forward dynamics by ABA and no passive forces: a pendulum chain of 5 links
//! (1 m, 1 kg rods) released 0.3–0.9 rad off the vertical, and the embedded default arm released
//! hanging down (joint2 = 2.8 rad, outside its URDF range: limits are off) with every other joint
//! 0.1–0.3 rad off zero, so that it swings and twists (from near upright it falls over and spins,
//! a motion that the first-order methods do not resolve even at 16 kHz). For each integrator and step `h = T / N`
//! (`N` a power of two), the error is `max_i |q_i(T) − q_ref,i(T)|` (rad) and the work the
//! wall-clock time of [`Simulator::step`] (one thread; its energy check included) per
//! simulated second, the least over repeated runs (so other processes disturb it least).
//!
//! Reference: RK4 with `2 N_ref` steps, `N_ref` 16 times the finest step charted. Richardson:
//! RK4's error at `2 N_ref` is about `|q(N_ref) − q(2 N_ref)| / 15`; that change is written to the
//! CSV and the chart refuses to be drawn unless every charted error is at least
//! [`MARGIN`] times larger.

use super::svg::{Figure, Line, Marker, Panel, Series, Style, COLORS};
use super::Table;
use spatial_dynamics_core::model::examples;
use spatial_dynamics_core::sim::{Integrator, Passive, SimConfig, SimError, Simulator, State};
use spatial_dynamics_core::{urdf, ForwardDynamicsMethod, Model, ModelOptions};
use std::time::{Duration, Instant};

/// Final time (s).
const T_END: f64 = 1.0;
/// Every charted error is at least this many times the reference's Richardson change.
pub const MARGIN: f64 = 100.0;

/// One problem: a model and its start.
struct Problem {
    name: &'static str,
    model: Model,
    q0: Vec<f64>,
}

fn problems() -> Result<Vec<Problem>, String> {
    let load = |text: &str| {
        urdf::model_from_str(text, &ModelOptions::default()).map_err(|e| e.to_string())
    };
    Ok(vec![
        Problem {
            name: "pendulum chain, 5 links",
            model: load(&examples::pendulum_urdf(5, 1.0, 1.0))?,
            q0: vec![0.9, -0.6, 0.5, -0.4, 0.3],
        },
        Problem {
            name: "default arm (sd_arm7), hanging",
            model: load(examples::DEFAULT_ARM_URDF)?,
            q0: vec![0.1, 2.8, 0.2, 0.3, -0.2, 0.3, 0.1],
        },
    ])
}

/// Steps per `T` charted, as powers of two: `(first, last)` exponents per integrator.
fn sweep(integrator: Integrator, quick: bool) -> (u32, u32) {
    match (integrator, quick) {
        (_, true) => (8, 10),
        (Integrator::Rk4, false) => (2, 10),
        (_, false) => (3, 14),
    }
}

/// `q(T)` from `q0` at rest in `steps` equal steps.
fn simulate(problem: &Problem, integrator: Integrator, steps: usize) -> Result<Vec<f64>, SimError> {
    let config = SimConfig {
        integrator,
        method: ForwardDynamicsMethod::Aba,
        dt: T_END / steps as f64,
        substeps: 1,
        passive: Passive::default(),
        ground: None,
    };
    let model = &problem.model;
    let mut sim = Simulator::new(model, config).expect("no contact points, nothing to look up");
    let mut state = State::at_rest(model, problem.q0.clone());
    let tau = vec![0.0; model.nv()];
    for _ in 0..steps {
        sim.step(model, &mut state, &tau)?;
    }
    Ok(state.q)
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// One run of the sweep.
struct Run {
    problem: &'static str,
    integrator: Integrator,
    steps: usize,
    /// `(error, seconds per simulated second)`, or why it stopped.
    result: Result<(f64, f64), SimError>,
    reference_change: f64,
}

pub fn chart(quick: bool) -> Result<(Figure, Table), String> {
    let mut runs = Vec::new();
    let mut panels = Vec::new();
    let mut reference_notes = Vec::new();
    for problem in problems()? {
        let finest = Integrator::ALL
            .iter()
            .map(|&i| sweep(i, quick).1)
            .max()
            .unwrap_or(0);
        let n_ref = 1usize << (finest + 4);
        let coarse = simulate(&problem, Integrator::Rk4, n_ref)
            .map_err(|e| format!("{}: reference: {e}", problem.name))?;
        let reference = simulate(&problem, Integrator::Rk4, 2 * n_ref)
            .map_err(|e| format!("{}: reference: {e}", problem.name))?;
        let change = max_abs_diff(&coarse, &reference);
        let mut problem_runs = Vec::new();
        for integrator in Integrator::ALL {
            let (first, last) = sweep(integrator, quick);
            for e in first..=last {
                let steps = 1usize << e;
                let result = timed(&problem, integrator, steps, quick)
                    .map(|(q, secs)| (max_abs_diff(&q, &reference), secs / T_END));
                problem_runs.push(Run {
                    problem: problem.name,
                    integrator,
                    steps,
                    result,
                    reference_change: change,
                });
            }
            eprintln!("chart work_precision: {}, {integrator} done", problem.name);
        }
        let smallest = problem_runs
            .iter()
            .filter_map(|r| r.result.as_ref().ok().map(|x| x.0))
            .fold(f64::INFINITY, f64::min);
        if smallest < MARGIN * change || change.is_nan() {
            return Err(format!(
                "{}: the reference is not converged enough: halving its step (RK4, h = 2^-{} s) \
                 changes q(T) by {change:.2e} rad, more than 1/{MARGIN} of the smallest error charted ({smallest:.2e})",
                problem.name,
                finest + 5
            ));
        }
        panels.push(panel(&problem, &problem_runs));
        reference_notes.push(reference_note(&problem, n_ref, change));
        runs.extend(problem_runs);
    }
    let mut notes = reference_notes;
    notes.extend(stopped_notes(&runs));
    let figure = Figure {
        title: "Integrators: error at T = 1 s against CPU time".into(),
        x_label: "CPU seconds per simulated second".into(),
        y_label: "max |q(T) − q_ref(T)| (rad)".into(),
        panels,
        columns: 2,
        legend_notes: vec![
            "Steps h = 1/2^k s along each line".into(),
            "(right: smaller h). Torque-free motion".into(),
            "under gravity from rest, ABA, no".into(),
            "passive forces. Time: least of repeated".into(),
            "runs, one thread, shared machine.".into(),
        ],
        notes,
        panel_size: Some((480.0, 360.0)),
    };
    Ok((figure, table(&runs)))
}

/// `q(T)` and the least wall-clock time of repeated runs (seconds): at least two runs and 0.1 s
/// in all, at most 20 runs (one run in quick mode).
fn timed(
    problem: &Problem,
    integrator: Integrator,
    steps: usize,
    quick: bool,
) -> Result<(Vec<f64>, f64), SimError> {
    let mut best = Duration::MAX;
    let mut total = Duration::ZERO;
    let mut runs = 0;
    loop {
        let start = Instant::now();
        let q = simulate(problem, integrator, steps)?;
        let elapsed = start.elapsed();
        best = best.min(elapsed);
        total += elapsed;
        runs += 1;
        if quick || runs >= 20 || (runs >= 2 && total.as_secs_f64() >= 0.1) {
            return Ok((q, best.as_secs_f64()));
        }
    }
}

fn panel(problem: &Problem, runs: &[Run]) -> Panel {
    let mut series = Vec::new();
    let line_of = |integrator: Integrator| -> Vec<(f64, f64)> {
        runs.iter()
            .filter(|r| r.integrator == integrator)
            .filter_map(|r| r.result.as_ref().ok().map(|&(err, secs)| (secs, err)))
            .collect()
    };
    for (i, integrator) in Integrator::ALL.into_iter().enumerate() {
        series.push(Series::new(
            integrator.name(),
            Style {
                color: COLORS[i],
                marker: Some(Marker::ALL[i]),
                filled: true,
                line: Line::Solid,
            },
            line_of(integrator),
        ));
    }
    // Slopes of order p (error ∝ h^p ∝ work^-p) through the finest point of a method of that order.
    for (integrator, p, label) in [
        (Integrator::SemiImplicitEuler, 1, "order 1"),
        (Integrator::Rk4, 4, "order 4"),
    ] {
        if let Some(&(w0, e0)) = line_of(integrator).last() {
            // From large errors to small, so the tag sits at the small end.
            let line = (0..=24)
                .map(|i| w0 * 10f64.powf(f64::from(i) * 0.25 - 5.0))
                .map(|w| (w, e0 * (w / w0).powi(-p)))
                .collect();
            series.push(Series::reference("slopes of order 1 and 4", line).tagged(label));
        }
    }
    Panel {
        title: problem.name.to_string(),
        series,
        notes: Vec::new(),
    }
}

/// What the reference is and how far it moves when its step is halved.
fn reference_note(problem: &Problem, n_ref: usize, change: f64) -> String {
    format!(
        "{}: reference RK4 with h = 1/{} s; halving h changes q(T) by {change:.1e} rad",
        problem.name,
        2 * n_ref
    )
}

fn stopped_notes(runs: &[Run]) -> Vec<String> {
    let mut notes: Vec<(String, Vec<String>)> = Vec::new();
    for r in runs {
        let Err(e) = &r.result else { continue };
        let why = match e {
            SimError::EnergyBlowUp { .. } => "energy created".to_string(),
            SimError::NonFinite { .. } => "state not finite".to_string(),
            SimError::NotConverged { .. } => "Newton not converged".to_string(),
            SimError::Dynamics { source, .. } => source.to_string(),
        };
        let key = format!("{}, {}: stopped ({why}) at h =", r.problem, r.integrator);
        let h = format!("1/{}", r.steps);
        match notes.iter_mut().find(|(k, _)| *k == key) {
            Some((_, hs)) => hs.push(h),
            None => notes.push((key, vec![h])),
        }
    }
    notes
        .into_iter()
        .map(|(key, hs)| format!("{key} {} s", hs.join(", ")))
        .collect()
}

fn table(runs: &[Run]) -> Table {
    let mut table = Table::new(&[
        "problem",
        "integrator",
        "steps",
        "h",
        "error",
        "cpu_s_per_sim_s",
        "reference_change",
        "status",
    ]);
    for r in runs {
        let (error, secs, status) = match &r.result {
            Ok((e, s)) => (e.to_string(), s.to_string(), "ok".to_string()),
            Err(e) => (String::new(), String::new(), format!("stopped: {e}")),
        };
        table.push(vec![
            r.problem.into(),
            r.integrator.name().into(),
            r.steps.to_string(),
            (T_END / r.steps as f64).to_string(),
            error,
            secs,
            r.reference_change.to_string(),
            status,
        ]);
    }
    table
}
