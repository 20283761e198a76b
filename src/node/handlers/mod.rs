//! What the node does with each input, service request and timer tick, free of DDS: each
//! handler is a method of [`NodeState`] that takes the decoded message (or request, or tick)
//! and returns what to publish ([`Outputs`]) or answer, counting what it received and dropped
//! in [`Health`] and logging through the node's [`Logger`]. The ROS plumbing (`super::endpoints`)
//! creates the endpoints, decodes what arrives, calls a handler and sends what it returns.
//!
//! - [`inputs`]: the subscribed topics (`joint_states`, commands, reference, base state,
//!   `robot_description`);
//! - [`services`]: the node's own services;
//! - [`timers`]: the simulation's publish timer and `/diagnostics`;
//! - [`parameters`]: parameter validation, changes taking effect, `use_sim_time`;
//! - [`finite`]: the guard that keeps non-finite numbers from leaving the node.

mod finite;
mod inputs;
mod parameters;
mod services;
mod timers;

pub use parameters::{apply_parameter, validate_parameter, validate_parameters};
pub use timers::simulation_timer;

use super::engine::clock::NodeClock;
use super::engine::Engine;
use super::health::Health;
use super::logging::{log, Logger};
use super::params::Settings;
use crate::ros::msgs::*;
use crate::ros::names::NameResolver;
use finite::Finite;
use std::sync::{Arc, Mutex};

/// The full names of the node's topics and services (remaps and namespace applied), as counted
/// in [`Health`] and shown on `/diagnostics`.
#[derive(Clone, Debug)]
pub struct Names {
    /// `joint_states`: read in serve mode, published in simulate mode.
    pub joint_states: String,
    pub effort_command: String,
    pub commands: String,
    pub joint_commands: String,
    pub reference: String,
    /// `~/base_state`: read in serve mode, published in simulate mode.
    pub base_state: String,
    pub robot_description: String,
    pub gravity: String,
    pub acceleration: String,
    pub residual: String,
    pub feedforward_effort: String,
    pub feedforward_commands: String,
    pub diagnostics: String,
    pub clock: String,
    pub tf: String,
    pub inverse_dynamics: String,
    pub forward_dynamics: String,
    pub mass_matrix: String,
    pub describe_model: String,
    pub frame_kinematics: String,
    pub linearize: String,
    pub reset: String,
    pub pause: String,
    pub step: String,
    /// The status name on `/diagnostics`, diagnostic_updater's: the node's name (no namespace,
    /// no slash), `": "`, the task.
    pub status: String,
}

impl Names {
    /// The names of node `node_name` under `resolver`'s namespace and remaps.
    pub fn resolve(resolver: &NameResolver, node_name: &str) -> Names {
        let r = |name: &str| resolver.resolve(name);
        Names {
            joint_states: r("joint_states"),
            effort_command: r("~/effort_command"),
            commands: r("~/commands"),
            joint_commands: r("~/joint_commands"),
            reference: r("~/reference"),
            base_state: r("~/base_state"),
            robot_description: r("robot_description"),
            gravity: r("~/gravity_effort"),
            acceleration: r("~/acceleration"),
            residual: r("~/effort_residual"),
            feedforward_effort: r("~/feedforward_effort"),
            feedforward_commands: r("~/feedforward_commands"),
            diagnostics: r("/diagnostics"),
            clock: r("/clock"),
            tf: r("/tf"),
            inverse_dynamics: r("~/inverse_dynamics"),
            forward_dynamics: r("~/forward_dynamics"),
            mass_matrix: r("~/mass_matrix"),
            describe_model: r("~/describe_model"),
            frame_kinematics: r("~/frame_kinematics"),
            linearize: r("~/linearize"),
            reset: r("~/reset"),
            pause: r("~/pause"),
            step: r("~/step"),
            status: format!("{node_name}: dynamics"),
        }
    }
}

/// What a handler gives to publish, each on its topic (none: nothing to publish there). Every
/// message here holds finite numbers only: a handler holds back (and counts) any other.
#[derive(Debug, Default)]
pub struct Outputs {
    pub gravity: Option<JointState>,
    pub acceleration: Option<JointDynamics>,
    pub residual: Option<JointState>,
    pub feedforward_effort: Option<JointState>,
    pub feedforward_commands: Option<Float64MultiArray>,
    /// Simulate mode: the simulated time on `/clock` (with `publish_clock`).
    pub clock: Option<Clock>,
    /// Simulate mode: the simulated robot's `joint_states`.
    pub joint_states: Option<JointState>,
    /// Simulate mode: the simulated floating base on `~/base_state`.
    pub base_state: Option<Odometry>,
    /// Simulate mode: world → floating base on `/tf` (with `publish_tf`).
    pub tf: Option<TFMessage>,
    pub diagnostics: Option<DiagnosticArray>,
}

/// Everything the handlers share: the engine (model, workspace, latest state and commands), the
/// counters, the node's clock and stamp policy, the parameter values in force, and the robot
/// description last received on the topic.
pub struct NodeState {
    pub engine: Engine,
    pub health: Health,
    pub clock: NodeClock,
    pub names: Names,
    /// The parameter values in force, shared with the parameter validator and set action.
    settings: Arc<Mutex<Settings>>,
    /// The latest usable description from `robot_description` (the topic), shared with the
    /// validator: a model parameter is checked against the model it would build.
    topic_description: Arc<Mutex<Option<String>>>,
    /// Why the latest robot description from the topic was ignored, once logged.
    ignored_description: Option<String>,
    /// When `/clock` going back was last logged, and how often it went back since.
    clock_went_back: (Option<std::time::Instant>, u64),
    logger: Logger,
}

impl NodeState {
    /// The state of a node serving `engine` (built from `settings`), with counters at zero.
    pub fn new(engine: Engine, settings: Settings, names: Names, logger: Logger) -> NodeState {
        NodeState {
            clock: NodeClock::new(&settings),
            engine,
            health: Health::new(logger.clone()),
            names,
            settings: Arc::new(Mutex::new(settings)),
            topic_description: Arc::new(Mutex::new(None)),
            ignored_description: None,
            clock_went_back: (None, 0),
            logger,
        }
    }

    /// The parameter values in force (shared: the parameter callbacks hold them too).
    pub fn settings(&self) -> Arc<Mutex<Settings>> {
        self.settings.clone()
    }

    /// The robot description last received on the topic (shared with the parameter validator).
    pub fn topic_description(&self) -> Arc<Mutex<Option<String>>> {
        self.topic_description.clone()
    }

    /// Serves `new` from now on. It takes over what the old engine held from the topics
    /// ([`Engine::take_over`]); what it cannot take is logged as a warning, and the effort
    /// residual the old engine still owed is counted dropped on `~/effort_residual`.
    fn replace_engine(&mut self, mut new: Engine) {
        let lost = new.take_over(&self.engine);
        if let Some(stamp) = self.engine.pending_residual() {
            let why = format!(
                "the model changed before the next joint state: no residual for the joint \
                 state stamped {}.{:09}",
                stamp.sec, stamp.nanosec
            );
            self.health.dropped(&self.names.residual, &why);
        }
        if !lost.is_empty() {
            log!(
                self.logger,
                Warn,
                "robot '{}' replaces robot '{}' without {}",
                new.model.name(),
                self.engine.model.name(),
                lost.join(", ")
            );
        }
        if new.simulated_time().is_some() {
            log!(
                self.logger,
                Info,
                "the simulation starts again at t = 0 from initial_positions, with no command in force"
            );
        }
        self.engine = new;
    }

    /// A copy of the parameter values in force.
    fn current_settings(&self) -> Result<Settings, String> {
        Ok(self.settings.lock().map_err(|e| e.to_string())?.clone())
    }
}

/// `message` if every number in it is finite; otherwise `None`, counted as held back on `topic`.
fn checked<M: Finite>(health: &mut Health, message: M, topic: &str) -> Option<M> {
    match message.non_finite() {
        None => Some(message),
        Some(field) => {
            health.dropped(topic, &format!("output held back: {field} is not finite"));
            None
        }
    }
}

#[cfg(test)]
pub(crate) mod test_support {
    //! Node states over small models with closed-form dynamics, for the handlers' tests.

    use super::*;
    use crate::node::logging::Level;
    use spatial_dynamics_core::model::examples::pendulum_urdf;

    /// Standard gravity (m/s²), the parameters' default.
    pub const G: f64 = 9.81;
    /// The test pendulum: one thin rod of this length (m) and mass (kg) hanging from the world
    /// on `joint1`, about y. About its pivot, I = m L² / 3; the effort that holds it at angle θ
    /// is m g (L/2) sin θ, so unheld it accelerates at θ̈ = −(3 g / 2L) sin θ.
    pub const LENGTH: f64 = 0.8;
    pub const MASS: f64 = 2.5;

    /// The pendulum's inertia about its pivot, m L² / 3.
    pub fn pendulum_inertia() -> f64 {
        MASS * LENGTH * LENGTH / 3.0
    }

    /// The effort that holds the pendulum at angle `theta`, m g (L/2) sin θ.
    pub fn pendulum_gravity(theta: f64) -> f64 {
        MASS * G * LENGTH / 2.0 * theta.sin()
    }

    /// Settings that serve the test pendulum.
    pub fn pendulum() -> Settings {
        Settings {
            robot_description: pendulum_urdf(1, LENGTH, MASS),
            ..Settings::default()
        }
    }

    /// The state of a node named `spatial_dynamics` in `/` with these settings.
    pub fn serving(settings: Settings) -> NodeState {
        let engine = Engine::from_settings(&settings, None).expect("the settings give a model");
        let resolver = NameResolver::new("/", "spatial_dynamics", &[]);
        let names = Names::resolve(&resolver, "spatial_dynamics");
        NodeState::new(engine, settings, names, Logger::new("test", Level::Debug))
    }

    impl NodeState {
        /// A publish tick run the moment it is due.
        pub fn simulation_tick_now(&mut self) -> Outputs {
            let now = std::time::Instant::now();
            self.simulation_tick(now, now)
        }
    }

    /// The lines the node logged at `level`.
    pub fn logged(state: &NodeState, level: Level) -> Vec<String> {
        let lines = state.logger.kept_lines().into_iter();
        lines.filter(|(l, _)| *l == level).map(|(_, m)| m).collect()
    }

    /// A stamp of `sec` s.
    pub fn at(sec: i32) -> Time {
        Time { sec, nanosec: 0 }
    }

    /// The pendulum's joint state at angle `theta`, rate `rate`, stamped `stamp`.
    pub fn pendulum_state(theta: f64, rate: f64, stamp: Time) -> JointState {
        JointState {
            header: Header {
                stamp,
                frame_id: "base".into(),
            },
            name: vec!["joint1".into()],
            position: vec![theta],
            velocity: vec![rate],
            effort: Vec::new(),
        }
    }

    /// `|a − b| ≤ 1e-9 · max(1, |b|)`, with both in the message.
    pub fn assert_close(a: f64, b: f64) {
        assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{a} vs {b}");
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::*;
    use super::*;
    use crate::node::logging::Level;

    #[test]
    fn a_non_finite_output_is_held_back_and_counted_on_its_topic() {
        let mut health = Health::new(Logger::new("test", Level::Info));
        let good = pendulum_state(0.1, 0.0, at(1));
        assert_eq!(
            checked(&mut health, good.clone(), "/out"),
            Some(good.clone())
        );
        let mut bad = good;
        bad.effort = vec![f64::NAN];
        assert_eq!(checked(&mut health, bad, "/out"), None);
        let reason = "output held back: effort[0] (joint 'joint1') is not finite";
        assert_eq!(health.dropped_on("/out", reason), 1);
        assert_eq!(health.total_dropped(), 1);
    }
}
