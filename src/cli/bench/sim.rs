//! The simulation kernels of `spatial_dynamics bench`: nanoseconds per step of the library's
//! [`Simulator`] (forward dynamics by ABA, by CRBA on models with mimic joints, no passive
//! forces, no contact, zero commanded efforts, gravity on), one kernel per integrator, timed over whole runs of `--sim-steps`
//! steps of `--sim-dt` from one initial state, nothing written on the way. The median repeat is
//! reported, with the state the run ends in (`q`, and `v` in the joints' velocity coordinates:
//! a floating joint's `[v_B; ω_B]`, both in the base frame), so another simulator's run of the
//! same length can be compared with it.

use clap::Args;
use serde_json::{json, Value};
use spatial_dynamics_core::sim::{Integrator, SimConfig, Simulator, State};
use spatial_dynamics_core::{ForwardDynamicsMethod, Model};
use std::hint::black_box;
use std::time::Instant;

/// The simulation kernels; timed only when named in `--kernels`.
pub const SIM_KERNELS: [&str; 2] = ["sim_rk4", "sim_semi_implicit_euler"];

/// The most steps in one timed run.
pub const MAX_SIM_STEPS: usize = 1_000_000_000;

/// The run each simulation kernel times.
#[derive(Args, Clone, Debug)]
pub struct SimSettings {
    /// Simulation kernels (forward dynamics by ABA, by CRBA on models with mimic joints): steps
    /// per timed run, 1 to 1000000000.
    #[arg(long, default_value_t = 1000)]
    pub sim_steps: usize,
    /// Simulation kernels: the step, seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 1e-3)]
    pub sim_dt: f64,
    /// Simulation kernels: the initial state, a JSON object {"q": [...], "v": [...]} in the
    /// model's coordinate order, nq and nv finite numbers; either key may be left out (default:
    /// the neutral configuration at rest). Checked even when no simulation kernel is timed.
    #[arg(long, value_name = "JSON")]
    pub sim_initial: Option<String>,
}

/// The integrator a simulation kernel name stands for.
pub fn integrator_of(kernel: &str) -> Option<Integrator> {
    kernel.strip_prefix("sim_")?.parse().ok()
}

/// The forward-dynamics method the simulation kernels use on `model`: ABA, or CRBA on a model
/// with mimic joints, which ABA cannot take (as `simulate` chooses by default).
pub fn method_for(model: &Model) -> ForwardDynamicsMethod {
    if model.has_mimic() {
        ForwardDynamicsMethod::Crba
    } else {
        ForwardDynamicsMethod::Aba
    }
}

impl SimSettings {
    /// The limits that do not depend on the model; the error names the flag.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_SIM_STEPS).contains(&self.sim_steps) {
            return Err(format!(
                "--sim-steps {}: must be 1 to {MAX_SIM_STEPS}",
                self.sim_steps
            ));
        }
        if !(self.sim_dt.is_finite() && self.sim_dt > 0.0) {
            return Err(format!(
                "--sim-dt {}: must be a positive number of seconds",
                self.sim_dt
            ));
        }
        Ok(())
    }

    /// The initial state; the error names the flag, and the key that is wrong.
    pub fn initial(&self, model: &Model) -> Result<State, String> {
        self.check()?;
        let mut state = State::at_rest(model, model.neutral());
        let Some(text) = &self.sim_initial else {
            return Ok(state);
        };
        let value: Value =
            serde_json::from_str(text).map_err(|e| format!("--sim-initial: not JSON: {e}"))?;
        let Value::Object(fields) = value else {
            return Err(format!(
                "--sim-initial: expected a JSON object {{\"q\": [...], \"v\": [...]}}, got {text}"
            ));
        };
        if let Some(key) = fields.keys().find(|k| !["q", "v"].contains(&k.as_str())) {
            return Err(format!(
                "--sim-initial: unknown key \"{key}\" (the keys are \"q\" and \"v\")"
            ));
        }
        for (key, target) in [("q", &mut state.q), ("v", &mut state.v)] {
            let Some(given) = fields.get(key) else {
                continue;
            };
            let numbers: Option<Vec<f64>> = given
                .as_array()
                .and_then(|a| a.iter().map(Value::as_f64).collect());
            match numbers {
                Some(n) if n.len() == target.len() && n.iter().all(|x| x.is_finite()) => {
                    target.copy_from_slice(&n)
                }
                _ => {
                    return Err(format!(
                        "--sim-initial: \"{key}\" must be an array of {} finite numbers",
                        target.len()
                    ))
                }
            }
        }
        Ok(state)
    }
}

/// One kernel's result: median nanoseconds per step and the state a run ends in.
pub struct SimTiming {
    pub ns_per_step: f64,
    pub end: State,
}

impl SimTiming {
    /// `{"q": [...], "v": [...]}` of the end state.
    pub fn end_json(&self) -> Value {
        json!({"q": self.end.q, "v": self.end.v})
    }
}

/// Times `integrator` on `model` from `initial` (see [`SimSettings::initial`]): one untimed run
/// (the end state, and the warm-up), then `repeats` timed runs from the same initial state; the
/// median per step.
pub fn time_simulation(
    model: &Model,
    integrator: Integrator,
    initial: &State,
    settings: &SimSettings,
    timing: &super::Settings,
) -> Result<SimTiming, String> {
    settings.check()?;
    timing.check()?;
    let config = SimConfig {
        integrator,
        method: method_for(model),
        dt: settings.sim_dt,
        ..SimConfig::default()
    };
    let tau = vec![0.0; model.nv()];
    let mut sim = Simulator::new(model, config)?;
    sim.set_instruction_set(timing.instruction_set());
    let mut state = initial.clone();
    let mut run = |state: &mut State| -> Result<f64, String> {
        state.clone_from(initial);
        sim.restart_energy_budget();
        let start = Instant::now();
        for _ in 0..settings.sim_steps {
            black_box(sim.step(model, black_box(&mut *state), &tau))
                .map_err(|e| format!("sim_{integrator}: {e}"))?;
        }
        Ok(start.elapsed().as_nanos() as f64 / settings.sim_steps as f64)
    };
    run(&mut state)?;
    let end = state.clone();
    let mut samples: Vec<f64> = super::try_with_capacity(timing.repeats, "--repeats")?;
    for _ in 0..timing.repeats {
        samples.push(run(&mut state)?);
    }
    samples.sort_by(f64::total_cmp);
    Ok(SimTiming {
        ns_per_step: (samples[samples.len() / 2] * 10.0).round() / 10.0,
        end,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use spatial_dynamics_core::model::examples;
    use spatial_dynamics_core::urdf::model_from_str;
    use spatial_dynamics_core::ModelOptions;

    #[test]
    fn kernel_names_map_to_their_integrators() {
        assert_eq!(integrator_of("sim_rk4"), Some(Integrator::Rk4));
        assert_eq!(
            integrator_of("sim_semi_implicit_euler"),
            Some(Integrator::SemiImplicitEuler)
        );
        assert_eq!(integrator_of("rnea"), None);
        assert!(SIM_KERNELS.iter().all(|k| integrator_of(k).is_some()));
    }

    /// A uniform rod pendulum (1 m, 1 kg: θ̈ = −(3g / 2l) sin θ) released from rest at θ₀ = 0.3:
    /// after 0.1 s, θ ≈ θ₀ − ½ (3g / 2) sin θ₀ t² (the t⁴ term is below 3e-4); a wrong-length
    /// initial state is refused.
    #[test]
    fn the_end_state_is_the_state_after_the_run() {
        let urdf = examples::pendulum_urdf(1, 1.0, 1.0);
        let model = model_from_str(&urdf, &ModelOptions::default()).unwrap();
        let settings = SimSettings {
            sim_steps: 100,
            sim_dt: 1e-3,
            sim_initial: Some(r#"{"q": [0.3], "v": [0.0]}"#.into()),
        };
        let timing = crate::cli::bench::Settings {
            states: 1,
            repeats: 1,
            min_time: 1e-3,
            baseline_instructions: false,
        };
        let initial = settings.initial(&model).unwrap();
        let t = time_simulation(&model, Integrator::Rk4, &initial, &settings, &timing).unwrap();
        assert!(t.ns_per_step > 0.0);
        let expected = 0.3 - 0.5 * 1.5 * 9.81 * 0.3f64.sin() * 0.01;
        assert!((t.end.q[0] - expected).abs() < 2e-3, "{}", t.end.q[0]);
        assert!(t.end.v[0] < 0.0);
        let bad = SimSettings {
            sim_initial: Some(r#"{"q": [0.3, 1.0]}"#.into()),
            ..settings
        };
        let err = bad.initial(&model).err().unwrap();
        assert!(err.contains("\"q\" must be an array of 1"), "{err}");
    }
}
