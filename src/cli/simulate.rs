//! `spatial_dynamics simulate`: integrate forward dynamics from an initial state under constant
//! efforts and write the trajectory as CSV: `time`, then `<joint>.position` and
//! `<joint>.velocity` for every coordinate (multi-dof joints: `<joint>.position[k]`), then
//! `energy` (T + V, J). Scenes that need it touch a ground plane at contact points (the `lamp`
//! scene at its foot's corners). A run that diverges keeps the rows written so far, says when and why,
//! and exits non-zero; a run that fails otherwise leaves no file (and an earlier one as it was).

use super::ModelArgs;
use crate::output_file::{same_file, PartialFile};
use clap::Args;
use spatial_dynamics_core::error::{name_list, quoted};
use spatial_dynamics_core::model::{quaternion_is_usable, quaternion_norm, JointKind};
use spatial_dynamics_core::sim::{
    ContactPoint, Ground, Integrator, Passive, SimConfig, Simulator, State,
};
use spatial_dynamics_core::spatial::Vector3;
use spatial_dynamics_core::{ForwardDynamicsMethod, Model};
use std::collections::BTreeSet;
use std::io::Write;
use std::path::PathBuf;

/// The most rows (steps) a run may write: about 3 hours at 1 kHz.
const MAX_ROWS: f64 = 1e7;
/// The most sub-steps a run may take in all.
const MAX_SUBSTEPS: f64 = 1e9;

/// Options of `simulate`.
#[derive(Args, Debug, Clone)]
pub struct SimulateArgs {
    /// explicit_euler, semi_implicit_euler, rk4 or implicit_euler.
    #[arg(long)]
    integrator: Integrator,
    /// Step, seconds.
    #[arg(long)]
    dt: f64,
    /// Simulated time, seconds: a whole number of steps, at most 10⁷ of them.
    #[arg(long)]
    duration: f64,
    /// Sub-steps per step, at least 1 (rows are written once per step; at most 10⁹ sub-steps
    /// in all).
    #[arg(long, default_value_t = 1)]
    substeps: usize,
    /// Forward-dynamics method: aba, crba or rnea_columns (default: aba; crba on a model with
    /// mimic joints, which aba cannot take).
    #[arg(long)]
    method: Option<ForwardDynamicsMethod>,
    /// Initial positions, {"joint": value} (arrays for multi-dof joints); others start at zero
    /// (a floating base at the origin, unrotated).
    #[arg(long, value_name = "JSON")]
    initial: Option<String>,
    /// Constant efforts, {"joint": value} (arrays for multi-dof joints); others get zero.
    #[arg(long, value_name = "JSON")]
    effort: Option<String>,
    /// Passive joint forces from the URDF: a comma-separated list of damping, friction,
    /// effort_limits, position_limits, or all, or none.
    #[arg(long, default_value = "none")]
    passive: String,
    /// Efforts act until this time (s, at least 0), then drop to zero (default: the whole run).
    #[arg(long, value_name = "S")]
    effort_until: Option<f64>,
    /// A ground contact point, LINK:X,Y,Z in the link's frame (repeatable). The `lamp` scene
    /// has the four corners of its foot by default.
    #[arg(long = "contact", value_name = "LINK:X,Y,Z")]
    contacts: Vec<String>,
    /// Ground plane height (m), stiffness (N/m), damping (N·s/m) and friction coefficient.
    #[arg(long, default_value_t = Ground::default().height)]
    ground_height: f64,
    #[arg(long, default_value_t = Ground::default().stiffness)]
    ground_stiffness: f64,
    #[arg(long, default_value_t = Ground::default().damping)]
    ground_damping: f64,
    #[arg(long, default_value_t = Ground::default().friction)]
    ground_friction: f64,
    /// Output CSV file.
    #[arg(long)]
    output: PathBuf,
}

/// Runs the simulation.
pub fn run(model_args: &ModelArgs, args: &SimulateArgs) -> Result<(), String> {
    let model = model_args.load()?;
    let valid =
        args.dt > 0.0 && args.dt.is_finite() && args.duration >= 0.0 && args.duration.is_finite();
    if !valid {
        return Err(format!(
            "--dt must be positive and --duration non-negative, got {} and {}",
            args.dt, args.duration
        ));
    }
    let steps = whole_steps(args.duration, args.dt)?;
    if args.substeps == 0 {
        return Err("--substeps must be at least 1".into());
    }
    if steps as f64 * args.substeps as f64 > MAX_SUBSTEPS {
        return Err(format!(
            "--substeps {} over {steps} steps is more than {MAX_SUBSTEPS:e} sub-steps",
            args.substeps
        ));
    }
    if let Some(until) = args.effort_until.filter(|t| t.is_nan() || *t < 0.0) {
        return Err(format!(
            "--effort-until must be a time of at least 0 s, got {until}"
        ));
    }
    if let Some(urdf) = model_args
        .urdf
        .as_deref()
        .filter(|u| same_file(u, &args.output))
    {
        return Err(format!(
            "--output {} is the model's file {}: the trajectory would replace it",
            args.output.display(),
            urdf.display()
        ));
    }
    let method = match args.method {
        None if model.has_mimic() => ForwardDynamicsMethod::Crba,
        None => ForwardDynamicsMethod::Aba,
        Some(ForwardDynamicsMethod::Aba) if model.has_mimic() => {
            return Err(
                "--method aba cannot take a model with mimic joints: use crba or rnea_columns"
                    .into(),
            )
        }
        Some(method) => method,
    };
    let mut q = model.neutral();
    apply_map(
        &model,
        args.initial.as_deref(),
        "--initial",
        Column::Position,
        &mut q,
    )?;
    let mut tau = vec![0.0; model.nv()];
    apply_map(
        &model,
        args.effort.as_deref(),
        "--effort",
        Column::Velocity,
        &mut tau,
    )?;
    let config = SimConfig {
        integrator: args.integrator,
        method,
        dt: args.dt,
        substeps: args.substeps,
        passive: Passive::from_names(args.passive.split(','))
            .map_err(|e| format!("--passive: {e}"))?,
        ground: ground(model_args, args)?,
    };
    let zero = vec![0.0; model.nv()];
    let mut sim = Simulator::new(&model, config)?;
    let mut state = State::at_rest(&model, q);
    // The initial state is checked before anything is written.
    let mut energy = sim
        .energy(&model, &state)
        .map_err(|e| format!("--initial: {e}"))?;
    let partial = PartialFile::beside(&args.output).map_err(|e| format!("--output {e}"))?;
    let file = std::fs::File::create(&partial.path)
        .map_err(|e| format!("{}: {e}", args.output.display()))?;
    let mut out = std::io::BufWriter::new(file);
    let write_err = |e: std::io::Error| format!("{}: {e}", args.output.display());
    writeln!(out, "{}", header(&model)).map_err(write_err)?;
    for step in 0..=steps {
        if step > 0 {
            energy = sim.energy(&model, &state).map_err(|e| e.to_string())?;
        }
        write_row(&mut out, step as f64 * args.dt, &state, energy).map_err(write_err)?;
        if step == steps {
            break;
        }
        let active = args
            .effort_until
            .is_none_or(|until| state.t < until - 1e-12);
        if let Err(e) = sim.step(&model, &mut state, if active { &tau } else { &zero }) {
            out.flush().map_err(write_err)?;
            partial.keep_as(&args.output)?;
            return Err(format!("the simulation diverged {e} ({} with dt = {} s, method {}; the rows up to then are in {})", args.integrator, args.dt, method, args.output.display()));
        }
    }
    out.flush().map_err(write_err)?;
    drop(out);
    partial.keep_as(&args.output)?;
    if sim.max_penetration() > 0.0 {
        eprintln!(
            "spatial_dynamics: deepest ground penetration {:.6} m",
            sim.max_penetration()
        );
    }
    if sim.clamped() > 0 {
        eprintln!(
            "spatial_dynamics: efforts were clamped to their URDF limits in {} evaluations",
            sim.clamped()
        );
    }
    if sim.halved_steps() > 0 {
        eprintln!(
            "spatial_dynamics: implicit Euler halved {} steps whose Newton iterations did not converge",
            sim.halved_steps()
        );
    }
    Ok(())
}

/// The number of steps of `dt` in `duration`, which must be whole (to a part in 10⁹) and at
/// most [`MAX_ROWS`].
fn whole_steps(duration: f64, dt: f64) -> Result<usize, String> {
    let steps = duration / dt;
    if steps > MAX_ROWS {
        return Err(format!(
            "--duration {duration} s at --dt {dt} s is {steps:e} steps, more than {MAX_ROWS:e}"
        ));
    }
    let whole = steps.round();
    if (steps - whole).abs() > 1e-9 * whole.max(1.0) {
        return Err(format!(
            "--duration {duration} s is not a whole number of --dt {dt} s steps ({steps})"
        ));
    }
    Ok(whole as usize)
}

/// The ground contact asked for, if any: `--contact` points, or the scene's own. Each
/// `--ground-*` number is checked (naming its flag), contacts or not.
fn ground(model_args: &ModelArgs, args: &SimulateArgs) -> Result<Option<Ground>, String> {
    let numbers = Ground {
        height: args.ground_height,
        stiffness: args.ground_stiffness,
        damping: args.ground_damping,
        friction: args.ground_friction,
        points: Vec::new(),
    };
    for (flag, value) in [
        ("height", numbers.height),
        ("stiffness", numbers.stiffness),
        ("damping", numbers.damping),
        ("friction", numbers.friction),
    ] {
        let mut one = Ground::default();
        *match flag {
            "height" => &mut one.height,
            "stiffness" => &mut one.stiffness,
            "damping" => &mut one.damping,
            _ => &mut one.friction,
        } = value;
        one.check().map_err(|e| format!("--ground-{flag}: {e}"))?;
    }
    let mut points = args
        .contacts
        .iter()
        .map(|spec| {
            spec.parse::<ContactPoint>()
                .map_err(|e| format!("--contact: {e}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if points.is_empty()
        && model_args.builtin.as_deref() == Some("lamp")
        && model_args.urdf.is_none()
    {
        // The lamp's foot is a 0.20 × 0.10 × 0.04 m box whose bottom face is at z = 0 of its frame.
        points = [(0.1, 0.05), (0.1, -0.05), (-0.1, 0.05), (-0.1, -0.05)]
            .iter()
            .map(|&(x, y)| ContactPoint {
                link: "foot".into(),
                point: Vector3::new(x, y, 0.0),
            })
            .collect();
    }
    if points.is_empty() {
        return Ok(None);
    }
    Ok(Some(Ground { points, ..numbers }))
}

#[derive(Clone, Copy, PartialEq)]
enum Column {
    Position,
    Velocity,
}

/// Sets values from a `{"joint": number | [numbers]}` map.
fn apply_map(
    model: &Model,
    json: Option<&str>,
    flag: &str,
    column: Column,
    out: &mut [f64],
) -> Result<(), String> {
    let Some(json) = json else { return Ok(()) };
    let Entries(entries) = serde_json::from_str(json)
        .map_err(|e| format!("{flag}: expected {{\"joint\": value}}: {e}"))?;
    let mut named = BTreeSet::new();
    for (name, value) in entries {
        if !named.insert(name.clone()) {
            return Err(format!("{flag}: joint {} is named twice", quoted(&name)));
        }
        let joint = model
            .coordinate_joints()
            .find(|j| j.name == name)
            .ok_or_else(|| {
                let joints: Vec<&str> = model.coordinate_joints().map(|j| j.name).collect();
                format!(
                    "{flag}: unknown joint {} (joints: {})",
                    quoted(&name),
                    name_list(&joints, joints.len())
                )
            })?;
        let (start, len) = match column {
            Column::Position => (joint.q_index, joint.nq),
            Column::Velocity => (joint.v_index, joint.nv),
        };
        let values: Vec<f64> = match &value {
            serde_json::Value::Number(n) => n.as_f64().into_iter().collect(),
            serde_json::Value::Array(items) => {
                items.iter().filter_map(serde_json::Value::as_f64).collect()
            }
            _ => Vec::new(),
        };
        if values.len() != len
            || values.iter().any(|x| !x.is_finite())
            || (matches!(value, serde_json::Value::Array(ref a) if a.len() != len))
        {
            return Err(format!(
                "{flag}: joint '{name}' needs {len} finite number(s), got {value}"
            ));
        }
        out[start..start + len].copy_from_slice(&values);
        if column == Column::Position && *joint.kind == JointKind::Floating {
            // The quaternion as the simulator keeps it, unit from the first row on.
            let quat = &mut out[start + 3..start + 7];
            if !quaternion_is_usable(quat) {
                return Err(format!(
                    "{flag}: joint '{name}': the quaternion (x, y, z, w) {value} is (nearly) zero \
                     or too large to normalise"
                ));
            }
            let norm = quaternion_norm(quat);
            quat.iter_mut().for_each(|x| *x /= norm);
        }
    }
    Ok(())
}

/// A JSON object's entries in their order, every one kept (a map would keep only the last of
/// a name given twice).
struct Entries(Vec<(String, serde_json::Value)>);

impl<'de> serde::Deserialize<'de> for Entries {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Entries;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<Entries, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = map.next_entry()? {
                    entries.push(entry);
                }
                Ok(Entries(entries))
            }
        }
        deserializer.deserialize_map(Visitor)
    }
}

fn header(model: &Model) -> String {
    let mut cols = vec!["time".to_string()];
    for (column, n) in [
        ("position", Column::Position),
        ("velocity", Column::Velocity),
    ] {
        for j in model.coordinate_joints() {
            let count = if n == Column::Position { j.nq } else { j.nv };
            if count == 1 {
                cols.push(format!("{}.{column}", j.name));
            } else {
                cols.extend((0..count).map(|k| format!("{}.{column}[{k}]", j.name)));
            }
        }
    }
    cols.push("energy".into());
    cols.join(",")
}

fn write_row(out: &mut impl Write, time: f64, state: &State, energy: f64) -> std::io::Result<()> {
    write!(out, "{time}")?;
    for x in state.q.iter().chain(&state.v) {
        write!(out, ",{x}")?;
    }
    writeln!(out, ",{energy}")
}
