//! `spatial_dynamics bench`: nanoseconds per call of each algorithm on one model.
//!
//! Random states (at least 1000 by default, unit quaternions for floating joints) are drawn
//! before any timing and cycled through, so the caches and branch predictors see changing
//! inputs. Each kernel is warmed up, then timed over several repeats of whole passes through the
//! states (one `Instant` around many calls); the median repeat is reported.
//!
//! Besides the dynamics [`KERNELS`], the [`KINEMATICS_KERNELS`]: `frame_jacobian` (the
//! `world` Jacobian of one link, the one carried by the body deepest in the tree, named in the
//! JSON as `"frame"`) and `center_of_mass` (the centre of mass with its Jacobian); then the
//! [`DERIVATIVE_KERNELS`]: `rnea_derivatives` (`∂τ/∂q`, `∂τ/∂q̇`, `H` at `(q, q̇, q̈)`) and
//! `aba_derivatives` (`∂q̈/∂q`, `∂q̈/∂q̇`, `H⁻¹` at `(q, q̇, τ)`). The [`BATCH_KERNELS`]
//! (`rnea_rows`: RNEA on blocks of [`BATCH_ROWS`] states, ns per state) and the [`SIM_KERNELS`] (one
//! simulation step, see [`sim`]) run only when `--kernels` names them; the JSON then also has
//! `"sim_end"`: per simulation kernel the state its run ends in.

mod sim;

pub use sim::{SimSettings, SIM_KERNELS};

use super::ModelArgs;
use clap::Args;
use serde_json::{json, Map, Value};
use spatial_dynamics_core::algorithms::method_choice::AUTO_TOLERANCE;
use spatial_dynamics_core::algorithms::{
    aba_derivatives, center_of_mass_jacobian, choose_method, crba, find_frame, forward_dynamics,
    frame_jacobian, gravity, rnea, rnea_derivatives, rnea_rows, ReferenceFrame,
};
use spatial_dynamics_core::flop_table;
use spatial_dynamics_core::sampling::{random_q, Rng};
use spatial_dynamics_core::{
    DynamicsError, Externals, ForwardDynamicsMethod, InstructionSet, Model, Workspace,
};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// How many states, how many repeats, how long each repeat lasts at least.
#[derive(Args, Clone, Copy, Debug)]
pub struct Settings {
    /// Number of random states, generated before timing and cycled through.
    #[arg(long, default_value_t = 1024)]
    pub states: usize,
    /// Number of timed repeats; the median is reported.
    #[arg(long, default_value_t = 7)]
    pub repeats: usize,
    /// Minimum duration of one repeat, seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.2)]
    pub min_time: f64,
    /// Run the library's dispatched passes in the baseline instruction set (SSE2 on x86-64)
    /// instead of the fastest this processor runs (AVX2 and FMA where it has them).
    #[arg(long)]
    pub baseline_instructions: bool,
}

impl Settings {
    /// The instruction set the timed workspaces run in.
    pub fn instruction_set(&self) -> InstructionSet {
        if self.baseline_instructions {
            InstructionSet::Baseline
        } else {
            InstructionSet::best()
        }
    }

    /// The error names the flag that is out of range.
    pub fn check(&self) -> Result<(), String> {
        if self.states == 0 || self.repeats == 0 {
            return Err("--states and --repeats must be at least 1".into());
        }
        if !(self.min_time.is_finite() && self.min_time > 0.0) {
            return Err("--min-time must be a positive number of seconds".into());
        }
        Ok(())
    }
}

/// One random state: inputs for every kernel.
struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    /// Accelerations for `rnea`, efforts for forward dynamics.
    a_or_tau: Vec<f64>,
}

/// The kernels, in the order they are reported.
pub const KERNELS: [&str; 6] = [
    "rnea",
    "crba",
    "fd_aba",
    "fd_crba",
    "fd_rnea_columns",
    "gravity",
];

/// The kinematics kernels, reported after [`KERNELS`] (see the module documentation).
pub const KINEMATICS_KERNELS: [&str; 2] = ["frame_jacobian", "center_of_mass"];

/// The derivative kernels, reported last (see the module documentation).
pub const DERIVATIVE_KERNELS: [&str; 2] = ["rnea_derivatives", "aba_derivatives"];

/// The kernels over many states at once, timed only when `--kernels` names them; reported per
/// state.
pub const BATCH_KERNELS: [&str; 1] = ["rnea_rows"];

/// States per call of a batch kernel (the states cut into blocks of this many rows).
pub const BATCH_ROWS: usize = 64;

/// The link `frame_jacobian` is timed on: the one of the body with the most bodies above it
/// (the first such in model order), or the root link when nothing moves.
pub fn deepest_link(model: &Model) -> &str {
    let mut depth = vec![0usize; model.nbodies()];
    let mut deepest: Option<usize> = None;
    for (i, body) in model.bodies().iter().enumerate() {
        depth[i] = body.parent.map_or(1, |p| depth[p] + 1);
        if deepest.is_none_or(|d| depth[i] > depth[d]) {
            deepest = Some(i);
        }
    }
    deepest.map_or(model.root_link(), |i| model.bodies()[i].name.as_str())
}

/// Times every kernel (or those named in `only`) and prints the result; with a reduction asked
/// for, the full model too and the speed-up; and the method `auto` would choose.
pub fn run(
    args: &ModelArgs,
    as_json: bool,
    only: &[String],
    settings: &Settings,
    sim_settings: &SimSettings,
) -> Result<(), String> {
    settings.check()?;
    let model = args.load()?;
    let (sim_kernels, only): (Vec<&String>, Vec<&String>) =
        only.iter().partition(|k| SIM_KERNELS.contains(&k.as_str()));
    let sim_runs = sim_kernels
        .iter()
        .map(|k| {
            let integrator = sim::integrator_of(k).expect("a simulation kernel");
            sim::time_simulation(&model, integrator, sim_settings, settings)
                .map(|t| (k.as_str(), t))
        })
        .collect::<Result<Vec<_>, String>>()?;
    if only.is_empty() && !sim_runs.is_empty() {
        return print_sim_only(&model, as_json, &sim_runs, settings);
    }
    let all: Vec<&str> = KERNELS
        .iter()
        .chain(&KINEMATICS_KERNELS)
        .chain(&DERIVATIVE_KERNELS)
        .chain(&BATCH_KERNELS)
        .copied()
        .filter(|k| (only.is_empty() && !BATCH_KERNELS.contains(k)) || only.iter().any(|o| o == k))
        .collect();
    if let Some(unknown) = only.iter().find(|o| !all.contains(&o.as_str())) {
        return Err(format!("bench: unknown kernel '{unknown}'"));
    }
    let times = time_kernels(&model, &all, settings)?;
    let full = if args.reduces() {
        let full = args.without_reductions().load()?;
        let full_times = time_kernels(&full, &all, settings)?;
        Some((full, full_times))
    } else {
        None
    };
    // Forward dynamics may have no answer on a model whose kinematics still do (a massless
    // floating root): the choice is then reported as none, with the reason, beside the timings.
    let auto = choose_method(&model, AUTO_TOLERANCE, Duration::from_millis(50));
    let speedup = |k: usize| match (&full, times[k]) {
        (Some((_, f)), Some(ours)) => f[k].map(|f| f / ours),
        _ => None,
    };
    let results: Vec<(&str, Option<f64>)> = all.iter().copied().zip(times.clone()).collect();
    let (flops, gflops) = flops_per_call(&model, &results);
    if as_json {
        let per_call = |t: &[Option<f64>]| -> Map<String, Value> {
            all.iter()
                .zip(t)
                .map(|(k, ns)| (k.to_string(), json!(ns)))
                .collect()
        };
        let mut out = json!({"nv": model.nv(), "ns_per_call": per_call(&times), "flops_per_call": flops,
            "instruction_set": settings.instruction_set().name(),
                             "gflops": gflops, "frame": deepest_link(&model)});
        for (name, run) in &sim_runs {
            out["ns_per_call"][*name] = json!(run.ns_per_step);
            out["sim_end"][*name] = run.end_json();
        }
        match &auto {
            Ok(choice) => out["auto_method"] = json!(choice.method.name()),
            Err(e) => {
                out["auto_method"] = Value::Null;
                out["auto_method_error"] = json!(e.to_string());
            }
        }
        if let Some((full, full_times)) = &full {
            out["full"] = json!({"nv": full.nv(), "ns_per_call": per_call(full_times)});
            out["speedup"] = all
                .iter()
                .enumerate()
                .map(|(k, name)| {
                    (
                        name.to_string(),
                        json!(speedup(k).map(|x| (x * 100.0).round() / 100.0)),
                    )
                })
                .collect::<Map<String, Value>>()
                .into();
        }
        println!("{out}");
        return Ok(());
    }
    println!(
        "robot '{}': nq = {}, nv = {}; {} random states, median of {} repeats of at least {:.2} s",
        model.name(),
        model.nq(),
        model.nv(),
        settings.states,
        settings.repeats,
        settings.min_time
    );
    let cell = |ns: Option<f64>| ns.map_or("n/a (mimic)".to_string(), |x| format!("{x:.1}"));
    match &full {
        Some((full, full_times)) => {
            println!(
                "{:<16} {:>12} {:>16} {:>9}",
                "kernel",
                "ns/call",
                format!("full nv={}", full.nv()),
                "speed-up"
            );
            for (k, name) in all.iter().enumerate() {
                let up = speedup(k).map_or(String::new(), |x| format!("{x:.2}×"));
                println!(
                    "{name:<16} {:>12} {:>16} {up:>9}",
                    cell(times[k]),
                    cell(full_times[k])
                );
            }
        }
        None => {
            println!(
                "{:<16} {:>12} {:>12} {:>8}",
                "kernel", "ns/call", "FLOPs/call", "GFLOP/s"
            );
            for (name, ns) in &results {
                let rate = gflops[*name]
                    .as_f64()
                    .map_or(String::new(), |x| format!("{x:.2}"));
                println!(
                    "{name:<16} {:>12} {:>12} {rate:>8}",
                    cell(*ns),
                    flops[*name].to_string()
                );
            }
        }
    }
    for (name, run) in &sim_runs {
        println!("{name:<16} {:>12.1} (ns per step)", run.ns_per_step);
    }
    println!("frame_jacobian times link '{}'", deepest_link(&model));
    match &auto {
        Ok(choice) => println!("method auto would choose: {}", choice.summary()),
        Err(e) => println!("method auto would choose: none ({e})"),
    }
    Ok(())
}

/// The result when only simulation kernels were asked for: their ns per step (JSON: `"nv"`,
/// `"ns_per_call"` and `"sim_end"`).
fn print_sim_only(
    model: &Model,
    as_json: bool,
    runs: &[(&str, sim::SimTiming)],
    settings: &Settings,
) -> Result<(), String> {
    if as_json {
        let mut out = json!({"nv": model.nv(), "ns_per_call": {}, "sim_end": {},
            "instruction_set": settings.instruction_set().name()});
        for (name, run) in runs {
            out["ns_per_call"][*name] = json!(run.ns_per_step);
            out["sim_end"][*name] = run.end_json();
        }
        println!("{out}");
    } else {
        for (name, run) in runs {
            println!("{name:<24} {:>12.1} ns per step", run.ns_per_step);
        }
    }
    Ok(())
}

/// Per kernel, the floating-point operations of one call as implemented
/// ([`flop_table::kernel_flops`]) and the rate achieved, GFLOP/s (FLOPs per nanosecond).
fn flops_per_call(
    model: &Model,
    results: &[(&str, Option<f64>)],
) -> (Map<String, Value>, Map<String, Value>) {
    let mut flops_map = Map::new();
    let mut gflops_map = Map::new();
    for (name, ns) in results {
        let count = flop_table::kernel_flops(model, name).map(|f| f.total());
        flops_map.insert(name.to_string(), json!(count));
        let rate = match (count, ns) {
            (Some(count), Some(ns)) if *ns > 0.0 => {
                Some((count as f64 / ns * 100.0).round() / 100.0)
            }
            _ => None,
        };
        gflops_map.insert(name.to_string(), json!(rate));
    }
    (flops_map, gflops_map)
}

/// Median nanoseconds per call (to a tenth) of each of `kernels` (names from [`KERNELS`]) on
/// `model`, over `settings.states` seeded random states; `None` where the method refuses the
/// model (ABA with mimic joints). The same states for every kernel and every call.
pub fn time_kernels(
    model: &Model,
    kernels: &[&str],
    settings: &Settings,
) -> Result<Vec<Option<f64>>, String> {
    settings.check()?;
    let mut rng = Rng::new(0x5eed);
    let states: Vec<State> = (0..settings.states)
        .map(|_| State {
            q: random_q(model, &mut rng),
            v: rng.vector(model.nv(), 1.0),
            a_or_tau: rng.vector(model.nv(), 1.0),
        })
        .collect();
    kernels
        .iter()
        .map(|&name| {
            let known = [
                &KERNELS[..],
                &KINEMATICS_KERNELS,
                &DERIVATIVE_KERNELS,
                &BATCH_KERNELS,
            ];
            if !known.iter().any(|kernels| kernels.contains(&name)) {
                return Err(format!("bench: unknown kernel '{name}'"));
            }
            let ns = time_kernel(model, &states, name, settings)
                .map_err(|e| format!("bench {name}: {e}"))?;
            // Tenths of a nanosecond are more than the noise allows.
            Ok(ns.map(|x| (x * 10.0).round() / 10.0))
        })
        .collect()
}

/// Median nanoseconds per call of kernel `name`, or `None` when the method refuses the model
/// (ABA with mimic joints).
fn time_kernel(
    model: &Model,
    states: &[State],
    name: &str,
    settings: &Settings,
) -> Result<Option<f64>, DynamicsError> {
    use ForwardDynamicsMethod::{Aba, Crba, RneaColumns};
    let mut ws = Workspace::new(model);
    ws.set_instruction_set(settings.instruction_set());
    let ws = &mut ws;
    let fd = |ws: &mut Workspace, s: &State, method| {
        forward_dynamics(
            model,
            ws,
            &s.q,
            &s.v,
            &s.a_or_tau,
            method,
            &Externals::none(),
        )
        .map(sink)
    };
    match name {
        "rnea" => measure(states, settings, |s| {
            rnea(model, ws, &s.q, &s.v, &s.a_or_tau).map(sink)
        }),
        "crba" => measure(states, settings, |s| crba(model, ws, &s.q).map(sink)),
        "fd_aba" => measure(states, settings, |s| fd(ws, s, Aba)),
        "fd_crba" => measure(states, settings, |s| fd(ws, s, Crba)),
        "fd_rnea_columns" => measure(states, settings, |s| fd(ws, s, RneaColumns)),
        "gravity" => measure(states, settings, |s| gravity(model, ws, &s.q).map(sink)),
        "frame_jacobian" => {
            let frame = find_frame(model, deepest_link(model))?;
            let world = ReferenceFrame::World;
            measure(states, settings, |s| {
                frame_jacobian(model, ws, &s.q, &frame, world).map(sink)
            })
        }
        "center_of_mass" => measure(states, settings, |s| {
            center_of_mass_jacobian(model, ws, &s.q).map(sink)
        }),
        "rnea_derivatives" => measure(states, settings, |s| {
            rnea_derivatives(model, ws, &s.q, &s.v, &s.a_or_tau).map(sink)
        }),
        "aba_derivatives" => measure(states, settings, |s| {
            aba_derivatives(model, ws, &s.q, &s.v, &s.a_or_tau, &Externals::none()).map(sink)
        }),
        "rnea_rows" => {
            // Each block's rows contiguous, as `rnea_rows` reads them; ns per state.
            let blocks: Vec<State> = states
                .chunks(BATCH_ROWS)
                .map(|rows| State {
                    q: rows.iter().flat_map(|s| s.q.iter().copied()).collect(),
                    v: rows.iter().flat_map(|s| s.v.iter().copied()).collect(),
                    a_or_tau: rows
                        .iter()
                        .flat_map(|s| s.a_or_tau.iter().copied())
                        .collect(),
                })
                .collect();
            let mut tau = vec![0.0; BATCH_ROWS * model.nv()];
            let per_block = measure(&blocks, settings, |b| {
                let tau = &mut tau[..b.v.len()];
                rnea_rows(model, ws, &b.q, &b.v, &b.a_or_tau, tau).map_err(|(_, e)| e)
            })?;
            Ok(per_block.map(|ns| ns * blocks.len() as f64 / states.len() as f64))
        }
        _ => unreachable!("unknown kernel {name}"),
    }
}

/// Outputs go through `black_box`, so the work cannot be optimised away.
fn sink<T>(output: T) {
    black_box(output);
}

/// Median nanoseconds per `call`, cycling through `states`.
fn measure(
    states: &[State],
    settings: &Settings,
    mut call: impl FnMut(&State) -> Result<(), DynamicsError>,
) -> Result<Option<f64>, DynamicsError> {
    // One checked pass: every state must be accepted (ABA refuses mimic joints).
    for s in states {
        match call(s) {
            Ok(()) => {}
            Err(DynamicsError::Unsupported { .. }) => return Ok(None),
            Err(e) => return Err(e),
        }
    }
    let mut pass = || {
        let start = Instant::now();
        for s in states {
            // The result was checked above; here only its cost counts.
            let _ = black_box(call(black_box(s)));
        }
        start.elapsed()
    };
    // Warm-up (half a repeat's time), which also measures how many passes fill a repeat.
    let mut warm = Duration::ZERO;
    let mut warm_passes = 0u32;
    while warm.as_secs_f64() < settings.min_time / 2.0 || warm_passes == 0 {
        warm += pass();
        warm_passes += 1;
    }
    let per_pass = (warm / warm_passes).as_secs_f64().max(1e-9);
    let passes = ((settings.min_time / per_pass).ceil() as u32).max(1);
    let mut samples: Vec<f64> = (0..settings.repeats)
        .map(|_| {
            let total: Duration = (0..passes).map(|_| pass()).sum();
            total.as_nanos() as f64 / (f64::from(passes) * states.len() as f64)
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    Ok(Some(samples[samples.len() / 2]))
}
