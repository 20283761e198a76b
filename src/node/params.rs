//! The node's parameters: names, types, defaults, validation, and parameter files.
//!
//! | name | type | default | effect |
//! |---|---|---|---|
//! | `robot_description` | string | `""` | URDF text; wins over `urdf_file` and the topic |
//! | `urdf_file` | string | `""` | URDF file path, used when `robot_description` is empty |
//! | `floating_base` | bool | `false` | add a floating joint at the root link |
//! | `ignore_mimic` | bool | `false` | treat `<mimic>` joints as independent |
//! | `locked_joints` | string[] | `[]` | `"NAME=POSITION"`: joints frozen and fused |
//! | `root_link` | string | `""` | keep only this link's subtree (it becomes the fixed base); `""`: the URDF's root |
//! | `tip_links` | string[] | `[]` | keep only the joints from the root to these links; bodies past a tip lump onto it |
//! | `prune_massless` | bool | `false` | remove moving joints whose whole subtree is massless |
//! | `gravity` | double[3] | `[0, 0, -9.81]` | gravity in the world frame, m/s² |
//! | `method` | string | `auto` | forward dynamics: `aba`, `crba`, `rnea_columns`, or `auto`: of the methods that agree with `aba` to 1e-10 on this model, the one with the fewest FLOPs per call (the same choice on every run) |
//! | `command_joints` | string[] | `[]` | order of `~/commands` and `~/feedforward_commands` (empty: all joints in model order) |
//! | `mode` | string | `serve` | `serve`: dynamics of the measured state; `simulate`: the node owns and integrates the state |
//! | `publish_rate` | double | `100` | simulate: `joint_states` per second (Hz), 0.001 to 1e6 |
//! | `sim_dt` | double | `0.001` | simulate: integration step (s) |
//! | `integrator` | string | `semi_implicit_euler` | simulate: `explicit_euler`, `semi_implicit_euler`, `rk4`, `implicit_euler` |
//! | `real_time_factor` | double | `1.0` | simulate: simulated seconds per wall-clock second |
//! | `publish_clock` | bool | `false` | simulate: publish the simulated time on `/clock` |
//! | `command_timeout` | double | `0.5` | simulate: a command older than this (wall s) drops to zero effort; 0: never |
//! | `command_interface` | string | `effort` | simulate: what `~/commands` and `~/joint_commands` set: `effort`, `position` (PD servo) or `velocity` (damping servo) |
//! | `servo_kp`, `servo_kd` | double[] | `[100]`, `[10]` | simulate: servo gains, one value for every command joint or one per `command_joints` entry (N·m/rad, N·m·s/rad; N/m, N·s/m) |
//! | `step_mode` | string | `free` | simulate: `free` (the publish timer advances the state) or `on_command` (each accepted command advances it) |
//! | `steps_per_command` | integer | `1` | simulate, `on_command`: `sim_dt` steps per command |
//! | `publish_tf` | bool | `true` | simulate: a floating base's pose on `/tf` (world → base link) with each joint state |
//! | `passive` | string[] | `[]` | simulate: URDF forces applied: `damping`, `friction`, `effort_limits`, `position_limits` |
//! | `initial_positions` | string[] | `[]` | simulate: `"NAME=POSITION"` at start and on reload (others zero; a joint given twice is refused) |
//! | `ground_contacts` | string[] | `[]` | simulate: `"LINK:X,Y,Z"` points (link frame, m) that touch a ground plane; empty: no ground |
//! | `ground_height` | double | `0` | simulate: the plane `z = height` (world, m) |
//! | `ground_stiffness`, `ground_damping`, `ground_friction` | double | `2e4`, `200`, `0.8` | simulate: penalty contact per point: N/m, N·s/m, Coulomb μ (`src/core/sim/contact.rs`) |
//! | `use_sim_time` | bool | `false` | the node's clock is ROS simulated time: the latest `/clock` (simulate mode: its own simulated time); outputs are stamped with it |
//! | `max_stamp_age` | double | `0` | drop a `joint_states` stamped more than this (s) before the node's clock; 0: off, else ≥ 1e-9 |
//! | `future_stamp_tolerance` | double | `0` | drop a `joint_states` stamped more than this (s) after the node's clock; 0: off, else ≥ 1e-9 |
//!
//! Every parameter is declared, with its description, type and range
//! ([`super::parameter_descriptors`]). The simulate-mode parameters other than `publish_clock`
//! are read-only: they are read when the simulation is built. Every other parameter can be
//! changed at run time and takes effect at once (model parameters rebuild the model; a change
//! that would give an unusable model is refused). A parameter file's entries for parameters the
//! node does not have are ignored (the node warns once per file), as rclcpp ignores them. The clock and
//! stamp rules are those of [`super::engine::clock`]. `use_sim_time` is kept by ros2-client's
//! parameter store itself (every ROS node has it): our validator never sees it, so the node
//! reads its value from the store before each use.

use ros2_client::ParameterValue;
use spatial_dynamics_core::error::quoted;
use spatial_dynamics_core::model::joint_position;
use spatial_dynamics_core::sim::{CommandInterface, ContactPoint, Ground, Integrator, Passive};
use spatial_dynamics_core::spatial::Vector3;
use spatial_dynamics_core::{ForwardDynamicsMethod, ModelOptions};
use std::path::Path;

/// The parameter values in force.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub robot_description: String,
    pub urdf_file: String,
    pub floating_base: bool,
    pub ignore_mimic: bool,
    pub locked_joints: Vec<(String, f64)>,
    pub root_link: String,
    pub tip_links: Vec<String>,
    pub prune_massless: bool,
    pub gravity: [f64; 3],
    /// `None`: `auto` (measured when the model loads).
    pub method: Option<ForwardDynamicsMethod>,
    pub command_joints: Vec<String>,
    pub simulate: bool,
    pub publish_rate: f64,
    pub sim_dt: f64,
    pub integrator: Integrator,
    pub real_time_factor: f64,
    pub publish_clock: bool,
    pub command_timeout: f64,
    pub command_interface: CommandInterface,
    pub servo_kp: Vec<f64>,
    pub servo_kd: Vec<f64>,
    /// Simulate: each accepted command advances the state (`step_mode: on_command`).
    pub lockstep: bool,
    pub steps_per_command: usize,
    pub publish_tf: bool,
    pub passive: Vec<String>,
    pub initial_positions: Vec<(String, f64)>,
    /// Simulate: the ground plane and its contact points (no points: no ground).
    pub ground: Ground,
    pub use_sim_time: bool,
    pub max_stamp_age: f64,
    pub future_stamp_tolerance: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            robot_description: String::new(),
            urdf_file: String::new(),
            floating_base: false,
            ignore_mimic: false,
            locked_joints: Vec::new(),
            root_link: String::new(),
            tip_links: Vec::new(),
            prune_massless: false,
            gravity: [0.0, 0.0, -9.81],
            method: None,
            command_joints: Vec::new(),
            simulate: false,
            publish_rate: 100.0,
            sim_dt: 1e-3,
            integrator: Integrator::SemiImplicitEuler,
            real_time_factor: 1.0,
            publish_clock: false,
            command_timeout: 0.5,
            command_interface: CommandInterface::Effort,
            servo_kp: vec![100.0],
            servo_kd: vec![10.0],
            lockstep: false,
            steps_per_command: 1,
            publish_tf: true,
            passive: Vec::new(),
            initial_positions: Vec::new(),
            ground: Ground::default(),
            use_sim_time: false,
            max_stamp_age: 0.0,
            future_stamp_tolerance: 0.0,
        }
    }
}

/// When a change of a parameter takes effect (see the module's documentation).
#[derive(Clone, Copy)]
enum Takes {
    /// The model is rebuilt.
    Model,
    /// The node's clock and stamp policy change; neither the model nor the simulation does.
    Time,
    /// Read only when the simulation is built (at start, and from their values then whenever a
    /// model parameter rebuilds the model): read-only, as rclcpp declares such parameters.
    Start,
    /// At once, each parameter in its own way (`method`, `command_joints`, `publish_clock`).
    Own,
}

/// Every parameter, in declaration order, with when a change of it takes effect.
const PARAMETERS: [(&str, Takes); 34] = {
    use Takes::*;
    [
        ("robot_description", Model),
        ("urdf_file", Model),
        ("floating_base", Model),
        ("ignore_mimic", Model),
        ("locked_joints", Model),
        ("root_link", Model),
        ("tip_links", Model),
        ("prune_massless", Model),
        ("gravity", Model),
        ("method", Own),
        ("command_joints", Own),
        ("use_sim_time", Time),
        ("max_stamp_age", Time),
        ("future_stamp_tolerance", Time),
        ("mode", Start),
        ("publish_rate", Start),
        ("sim_dt", Start),
        ("integrator", Start),
        ("real_time_factor", Start),
        ("publish_clock", Own),
        ("command_timeout", Start),
        ("command_interface", Start),
        ("servo_kp", Start),
        ("servo_kd", Start),
        ("step_mode", Start),
        ("steps_per_command", Start),
        ("publish_tf", Start),
        ("passive", Start),
        ("initial_positions", Start),
        ("ground_contacts", Start),
        ("ground_height", Start),
        ("ground_stiffness", Start),
        ("ground_damping", Start),
        ("ground_friction", Start),
    ]
};

/// The names of the parameters that take effect as `takes` says (all of them for `None`), in
/// declaration order; `N` must be their number (checked when compiling).
const fn names<const N: usize>(takes: Option<Takes>) -> [&'static str; N] {
    let mut out = [""; N];
    let (mut i, mut found) = (0, 0);
    while i < PARAMETERS.len() {
        let (name, t) = PARAMETERS[i];
        let wanted = match takes {
            None => true,
            Some(w) => w as u8 == t as u8,
        };
        if wanted {
            assert!(found < N, "more parameters of this kind than N");
            out[found] = name;
            found += 1;
        }
        i += 1;
    }
    assert!(found == N, "fewer parameters of this kind than N");
    out
}

/// The names of all parameters, in declaration order.
pub const NAMES: [&str; 34] = names(None);

/// Parameters read only when the simulation is built (at start, and from their values then
/// whenever a model parameter rebuilds the model): read-only, as rclcpp declares such parameters.
pub const START_PARAMETERS: [&str; 19] = names(Some(Takes::Start));

/// Parameters of the node's clock and stamp policy (a change touches neither the model nor the
/// simulation).
pub const TIME_PARAMETERS: [&str; 3] = names(Some(Takes::Time));

/// Parameters that change the model (a change rebuilds it).
pub const MODEL_PARAMETERS: [&str; 9] = names(Some(Takes::Model));

impl Settings {
    /// Each parameter's current value, for declaring it.
    pub fn values(&self) -> Vec<(&'static str, ParameterValue)> {
        NAMES
            .iter()
            .map(|&n| (n, self.get(n).expect("every name has a value")))
            .collect()
    }

    /// The value of parameter `name`.
    pub fn get(&self, name: &str) -> Option<ParameterValue> {
        use ParameterValue as P;
        Some(match name {
            "robot_description" => P::String(self.robot_description.clone()),
            "urdf_file" => P::String(self.urdf_file.clone()),
            "floating_base" => P::Boolean(self.floating_base),
            "ignore_mimic" => P::Boolean(self.ignore_mimic),
            "locked_joints" => P::StringArray(
                self.locked_joints
                    .iter()
                    .map(|(n, v)| format!("{n}={v:?}"))
                    .collect(),
            ),
            "root_link" => P::String(self.root_link.clone()),
            "tip_links" => P::StringArray(self.tip_links.clone()),
            "prune_massless" => P::Boolean(self.prune_massless),
            "gravity" => P::DoubleArray(self.gravity.to_vec()),
            "method" => P::String(self.method.map_or("auto", |m| m.name()).to_string()),
            "command_joints" => P::StringArray(self.command_joints.clone()),
            "mode" => P::String(if self.simulate { "simulate" } else { "serve" }.into()),
            "publish_rate" => P::Double(self.publish_rate),
            "sim_dt" => P::Double(self.sim_dt),
            "integrator" => P::String(self.integrator.name().into()),
            "real_time_factor" => P::Double(self.real_time_factor),
            "publish_clock" => P::Boolean(self.publish_clock),
            "command_timeout" => P::Double(self.command_timeout),
            "command_interface" => P::String(self.command_interface.name().into()),
            "servo_kp" => P::DoubleArray(self.servo_kp.clone()),
            "servo_kd" => P::DoubleArray(self.servo_kd.clone()),
            "step_mode" => P::String(if self.lockstep { "on_command" } else { "free" }.into()),
            "steps_per_command" => P::Integer(self.steps_per_command as i64),
            "publish_tf" => P::Boolean(self.publish_tf),
            "passive" => P::StringArray(self.passive.clone()),
            "initial_positions" => P::StringArray(
                self.initial_positions
                    .iter()
                    .map(|(n, v)| format!("{n}={v:?}"))
                    .collect(),
            ),
            "ground_contacts" => {
                P::StringArray(self.ground.points.iter().map(|p| p.to_string()).collect())
            }
            "ground_height" => P::Double(self.ground.height),
            "ground_stiffness" => P::Double(self.ground.stiffness),
            "ground_damping" => P::Double(self.ground.damping),
            "ground_friction" => P::Double(self.ground.friction),
            "use_sim_time" => P::Boolean(self.use_sim_time),
            "max_stamp_age" => P::Double(self.max_stamp_age),
            "future_stamp_tolerance" => P::Double(self.future_stamp_tolerance),
            _ => return None,
        })
    }

    /// Sets parameter `name`, checking its type and value; the error says what is wrong.
    pub fn set(&mut self, name: &str, value: &ParameterValue) -> Result<(), String> {
        use ParameterValue as P;
        let wrong = |expected: &str| {
            Err(format!(
                "parameter '{name}' must be {expected}, got {value:?}"
            ))
        };
        match (name, value) {
            ("robot_description", P::String(s)) => self.robot_description = s.clone(),
            ("urdf_file", P::String(s)) => self.urdf_file = s.clone(),
            ("floating_base", P::Boolean(b)) => self.floating_base = *b,
            ("ignore_mimic", P::Boolean(b)) => self.ignore_mimic = *b,
            ("locked_joints", P::StringArray(items)) => {
                self.locked_joints = items
                    .iter()
                    .map(|s| parse_lock(s))
                    .collect::<Result<_, _>>()?
            }
            ("root_link", P::String(s)) => self.root_link = s.clone(),
            ("tip_links", P::StringArray(items)) => self.tip_links = items.clone(),
            ("prune_massless", P::Boolean(b)) => self.prune_massless = *b,
            ("gravity", P::DoubleArray(g)) if g.len() == 3 && g.iter().all(|x| x.is_finite()) => {
                self.gravity = [g[0], g[1], g[2]]
            }
            ("gravity", P::IntegerArray(g)) if g.len() == 3 => {
                self.gravity = [g[0] as f64, g[1] as f64, g[2] as f64]
            }
            ("gravity", _) => return wrong("three finite numbers [x, y, z] (m/s², world frame)"),
            ("method", P::String(s)) if s == "auto" => self.method = None,
            ("method", P::String(s)) => {
                let method = s
                    .parse()
                    .map_err(|e| format!("parameter 'method': {e}, or auto"))?;
                self.method = Some(method)
            }
            ("command_joints", P::StringArray(names)) => self.command_joints = names.clone(),
            ("mode", P::String(m)) if m == "serve" || m == "simulate" => {
                self.simulate = m == "simulate"
            }
            ("mode", _) => return wrong("'serve' or 'simulate'"),
            ("publish_rate", _)
                if !positive(value)
                    .is_some_and(|x| (MIN_PUBLISH_RATE..=MAX_PUBLISH_RATE).contains(&x)) =>
            {
                return wrong(&format!(
                    "a rate from {MIN_PUBLISH_RATE} to {MAX_PUBLISH_RATE:e} Hz"
                ));
            }
            ("publish_rate" | "sim_dt" | "real_time_factor", _) => {
                let x = positive(value).ok_or_else(|| {
                    format!("parameter '{name}' must be a positive number, got {value:?}")
                })?;
                *match name {
                    "publish_rate" => &mut self.publish_rate,
                    "sim_dt" => &mut self.sim_dt,
                    _ => &mut self.real_time_factor,
                } = x;
            }
            ("command_timeout" | "max_stamp_age" | "future_stamp_tolerance", _) => {
                let x = match value {
                    P::Double(x) => *x,
                    P::Integer(x) => *x as f64,
                    _ => f64::NAN,
                };
                if !(x >= 0.0 && x.is_finite()) {
                    return wrong("a number of seconds ≥ 0");
                }
                // Stamps are whole nanoseconds: a positive tolerance below one would round to
                // 0, which switches the check off.
                if name != "command_timeout" && x > 0.0 && x < 1e-9 {
                    return wrong("0 (off) or a number of seconds ≥ 1e-9");
                }
                *match name {
                    "command_timeout" => &mut self.command_timeout,
                    "max_stamp_age" => &mut self.max_stamp_age,
                    _ => &mut self.future_stamp_tolerance,
                } = x;
            }
            ("use_sim_time", P::Boolean(b)) => self.use_sim_time = *b,
            ("integrator", P::String(s)) => self.integrator = s.parse()?,
            ("publish_clock", P::Boolean(b)) => self.publish_clock = *b,
            ("publish_tf", P::Boolean(b)) => self.publish_tf = *b,
            ("command_interface", P::String(s)) => self.command_interface = s.parse()?,
            ("servo_kp" | "servo_kd", _) => {
                let gains = match value {
                    P::DoubleArray(g) => g.clone(),
                    P::IntegerArray(g) => g.iter().map(|&x| x as f64).collect(),
                    P::Double(x) => vec![*x],
                    P::Integer(x) => vec![*x as f64],
                    _ => vec![],
                };
                if gains.is_empty() || !gains.iter().all(|g| g.is_finite() && *g >= 0.0) {
                    return wrong("one or more finite gains ≥ 0");
                }
                *if name == "servo_kp" {
                    &mut self.servo_kp
                } else {
                    &mut self.servo_kd
                } = gains;
            }
            ("step_mode", P::String(m)) if m == "free" || m == "on_command" => {
                self.lockstep = m == "on_command"
            }
            ("step_mode", _) => return wrong("'free' or 'on_command'"),
            ("steps_per_command", P::Integer(n)) if (1..=1_000_000).contains(n) => {
                self.steps_per_command = *n as usize
            }
            ("steps_per_command", _) => return wrong("an integer from 1 to 1000000"),
            ("passive", P::StringArray(items)) => {
                parse_passive(items)?;
                self.passive = items.clone();
            }
            ("initial_positions", P::StringArray(items)) => {
                let positions: Vec<(String, f64)> = items
                    .iter()
                    .map(|s| parse_lock(s))
                    .collect::<Result<_, _>>()?;
                let mut seen = std::collections::HashSet::new();
                for (name, _) in &positions {
                    if !seen.insert(name) {
                        return Err(format!(
                            "parameter 'initial_positions': joint {} is given twice",
                            quoted(name)
                        ));
                    }
                }
                self.initial_positions = positions;
            }
            ("ground_contacts", P::StringArray(items)) => {
                self.ground.points = items
                    .iter()
                    .map(|s| s.parse::<ContactPoint>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| format!("ground_contacts: {e}"))?
            }
            ("ground_height" | "ground_stiffness" | "ground_damping" | "ground_friction", _) => {
                let mut ground = self.ground.clone();
                *match name {
                    "ground_height" => &mut ground.height,
                    "ground_stiffness" => &mut ground.stiffness,
                    "ground_damping" => &mut ground.damping,
                    _ => &mut ground.friction,
                } = match value {
                    P::Double(x) => *x,
                    P::Integer(x) => *x as f64,
                    _ => return wrong("a number"),
                };
                ground
                    .check()
                    .map_err(|e| format!("parameter '{name}': {e}"))?;
                self.ground = ground;
            }
            ("integrator" | "command_interface", _) => return wrong("a string"),
            ("publish_clock" | "use_sim_time" | "publish_tf", _) => return wrong("a bool"),
            ("passive" | "initial_positions" | "ground_contacts", _) => {
                return wrong("a list of strings")
            }
            ("robot_description" | "urdf_file" | "method" | "root_link", _) => {
                return wrong("a string")
            }
            ("floating_base" | "ignore_mimic" | "prune_massless", _) => return wrong("a bool"),
            ("locked_joints" | "command_joints" | "tip_links", _) => {
                return wrong("a list of strings")
            }
            _ => {
                return Err(format!(
                    "unknown parameter '{name}' (known: {})",
                    NAMES.join(", ")
                ))
            }
        }
        Ok(())
    }

    /// Model options from these settings.
    pub fn model_options(&self) -> ModelOptions {
        ModelOptions {
            floating_base: self.floating_base,
            ignore_mimic: self.ignore_mimic,
            gravity: Vector3::from(self.gravity),
            locked: self.locked_joints.clone(),
            root: (!self.root_link.is_empty()).then(|| self.root_link.clone()),
            tips: self.tip_links.clone(),
            prune_massless: self.prune_massless,
        }
    }

    /// Applies a `--params-file`: the `ros__parameters` of the entries that match this node
    /// (`/**`, `NAME`, `/NS/NAME`, `/**/NAME`), in file order. Returns the names of the
    /// parameters it ignored because the node does not have them.
    pub fn apply_file(
        &mut self,
        path: &Path,
        namespace: &str,
        node: &str,
    ) -> Result<Vec<String>, String> {
        let mut ignored = Vec::new();
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("--params-file {}: {e}", path.display()))?;
        let doc: serde_norway::Value = serde_norway::from_str(&text)
            .map_err(|e| format!("--params-file {}: {e}", path.display()))?;
        let full = format!("{}/{node}", namespace.trim_end_matches('/'));
        let serde_norway::Value::Mapping(entries) = doc else {
            return Err(format!(
                "--params-file {}: expected a mapping of node names",
                path.display()
            ));
        };
        for (key, body) in entries {
            let key = key.as_str().unwrap_or_default();
            let matches = key == "/**"
                || key == node
                || key == full
                || key == format!("/**/{node}")
                || key == format!("/{node}") && namespace == "/";
            if !matches {
                continue;
            }
            let Some(params) = body.get("ros__parameters") else {
                return Err(format!(
                    "--params-file {}: entry '{key}' has no ros__parameters",
                    path.display()
                ));
            };
            let mut flat = Vec::new();
            flatten("", params, &mut flat);
            for (name, value) in flat {
                if !NAMES.contains(&name.as_str()) {
                    ignored.push(name);
                    continue;
                }
                let value = parameter_value(&value).map_err(|e| {
                    format!("--params-file {}: parameter '{name}': {e}", path.display())
                })?;
                self.set(&name, &value)
                    .map_err(|e| format!("--params-file {}: {e}", path.display()))?;
            }
        }
        Ok(ignored)
    }

    /// Applies `-p NAME:=VALUE` (VALUE in YAML).
    pub fn apply_arg(&mut self, name: &str, value: &str) -> Result<(), String> {
        let yaml: serde_norway::Value =
            serde_norway::from_str(value).map_err(|e| format!("-p {name}:={value}: {e}"))?;
        let value = parameter_value(&yaml).map_err(|e| format!("-p {name}:={value}: {e}"))?;
        self.set(name, &value)
            .map_err(|e| format!("-p {name}: {e}"))
    }
}

/// The slowest and fastest `publish_rate` (Hz): a publish period from 1000 s down to 1 µs, which
/// the node's timers hold without overflowing (ten periods of lag are measured).
pub const MIN_PUBLISH_RATE: f64 = 1e-3;
pub const MAX_PUBLISH_RATE: f64 = 1e6;

/// A positive finite number (integers accepted).
fn positive(value: &ParameterValue) -> Option<f64> {
    match value {
        ParameterValue::Double(x) => Some(*x),
        ParameterValue::Integer(x) => Some(*x as f64),
        _ => None,
    }
    .filter(|x| *x > 0.0 && x.is_finite())
}

/// The passive forces named in `items`.
pub fn parse_passive(items: &[String]) -> Result<Passive, String> {
    Passive::from_names(items.iter().map(String::as_str)).map_err(|e| format!("passive: {e}"))
}

fn parse_lock(item: &str) -> Result<(String, f64), String> {
    joint_position(item).map_err(|e| format!("entry {e}"))
}

/// Nested mappings become dotted names, as ROS reads them.
fn flatten(
    prefix: &str,
    value: &serde_norway::Value,
    out: &mut Vec<(String, serde_norway::Value)>,
) {
    match value {
        serde_norway::Value::Mapping(m) => {
            for (k, v) in m {
                let key = k
                    .as_str()
                    .map(str::to_string)
                    .unwrap_or_else(|| format!("{k:?}"));
                let name = if prefix.is_empty() {
                    key
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(&name, v, out);
            }
        }
        v => out.push((prefix.to_string(), v.clone())),
    }
}

/// A YAML value as a ROS parameter value (integers in a list of floats become floats).
pub fn parameter_value(v: &serde_norway::Value) -> Result<ParameterValue, String> {
    use serde_norway::Value as Y;
    use ParameterValue as P;
    Ok(match v {
        Y::Bool(b) => P::Boolean(*b),
        Y::Number(n) if n.is_i64() => P::Integer(n.as_i64().unwrap_or_default()),
        Y::Number(n) => P::Double(n.as_f64().unwrap_or(f64::NAN)),
        Y::String(s) => P::String(s.clone()),
        Y::Sequence(items) if items.is_empty() => P::StringArray(Vec::new()),
        Y::Sequence(items) if items.iter().all(|i| i.is_bool()) => {
            P::BooleanArray(items.iter().filter_map(Y::as_bool).collect())
        }
        Y::Sequence(items) if items.iter().all(|i| i.is_i64()) => {
            P::IntegerArray(items.iter().filter_map(Y::as_i64).collect())
        }
        Y::Sequence(items) if items.iter().all(|i| i.is_number()) => {
            P::DoubleArray(items.iter().filter_map(Y::as_f64).collect())
        }
        Y::Sequence(items) if items.iter().all(|i| i.is_string()) => P::StringArray(
            items
                .iter()
                .filter_map(|i| i.as_str().map(str::to_string))
                .collect(),
        ),
        other => return Err(format!("unsupported value {other:?}")),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_and_arguments_set_parameters() {
        let dir = std::env::temp_dir().join(format!("sd_params_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("p.yaml");
        std::fs::write(&file, "/**:\n  ros__parameters:\n    method: crba\n    gravity: [0, 0, -1.62]\n    qos_overrides:\n      depth: 5\nother_node:\n  ros__parameters:\n    floating_base: true\n/robot/dyn:\n  ros__parameters:\n    locked_joints: ['joint7=0.5']\n    lidar_rate: 10.0\n").unwrap();
        let mut s = Settings::default();
        let ignored = s.apply_file(&file, "/robot", "dyn").unwrap();
        assert_eq!(ignored, vec!["qos_overrides.depth", "lidar_rate"]);
        assert_eq!(s.method, Some(ForwardDynamicsMethod::Crba));
        assert_eq!(s.gravity, [0.0, 0.0, -1.62]);
        assert!(!s.floating_base);
        assert_eq!(s.locked_joints, vec![("joint7".to_string(), 0.5)]);
        s.apply_arg("method", "rnea_columns").unwrap();
        assert_eq!(s.method, Some(ForwardDynamicsMethod::RneaColumns));
        for (name, value, why) in [
            ("method", "magic", "unknown forward-dynamics method 'magic'"),
            ("gravity", "[1, 2]", "three finite numbers"),
            ("floating_base", "yes please", "must be a bool"),
            ("locked_joints", "['j=x']", "NAME=POSITION"),
            ("nonsense", "1", "unknown parameter 'nonsense'"),
        ] {
            let err = s.apply_arg(name, value).unwrap_err();
            assert!(err.contains(why), "{name}:={value}: {err}");
        }
    }

    #[test]
    fn clock_parameters_are_checked() {
        let mut s = Settings::default();
        assert!(!s.use_sim_time && s.max_stamp_age == 0.0 && s.future_stamp_tolerance == 0.0);
        s.apply_arg("use_sim_time", "true").unwrap();
        s.apply_arg("max_stamp_age", "0.25").unwrap();
        s.apply_arg("future_stamp_tolerance", "1").unwrap();
        assert!(s.use_sim_time);
        assert_eq!((s.max_stamp_age, s.future_stamp_tolerance), (0.25, 1.0));
        assert_eq!(
            s.get("future_stamp_tolerance"),
            Some(ParameterValue::Double(1.0))
        );
        for (name, value, why) in [
            ("use_sim_time", "1", "must be a bool"),
            ("max_stamp_age", "-0.1", "must be a number of seconds ≥ 0"),
            (
                "future_stamp_tolerance",
                ".inf",
                "must be a number of seconds ≥ 0",
            ),
            ("max_stamp_age", "soon", "must be a number of seconds ≥ 0"),
            (
                "max_stamp_age",
                "1e-12",
                "must be 0 (off) or a number of seconds ≥ 1e-9",
            ),
        ] {
            let err = s.apply_arg(name, value).unwrap_err();
            assert!(
                err.contains(why) && err.contains(name),
                "{name}:={value}: {err}"
            );
        }
        assert_eq!(s.max_stamp_age, 0.25, "a refused value leaves the old one");
    }

    #[test]
    fn an_initial_position_given_twice_is_refused() {
        let mut s = Settings::default();
        s.apply_arg("initial_positions", "['joint1=0.5', 'joint2=1']")
            .unwrap();
        let err = s
            .apply_arg("initial_positions", "['joint1=0.5', 'joint1=1']")
            .unwrap_err();
        assert!(err.contains("joint 'joint1' is given twice"), "{err}");
        assert_eq!(s.initial_positions.len(), 2, "the earlier value stays");
    }
}
