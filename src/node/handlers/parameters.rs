//! Parameters at run time: the check before a value is accepted, the value stored, and the
//! change taken into effect (rebuilding the model, the method or the clock's policy).

use super::NodeState;
use crate::node::engine::{clock, Engine};
use crate::node::logging::log;
use crate::node::params::{self, Settings};
use ros2_client::ParameterValue;
use spatial_dynamics_core::ForwardDynamicsMethod;
use std::sync::Mutex;

/// Whether parameter `name` may take `value` (parameters the node does not have are left to
/// the parameter store): [`validate_parameters`] of that one.
pub fn validate_parameter(
    settings: &Mutex<Settings>,
    description: &Mutex<Option<String>>,
    name: &str,
    value: &ParameterValue,
) -> Result<(), String> {
    validate_parameters(settings, description, [(name, value)])
}

/// Whether the parameters may take these values together (`set_parameters_atomically`; the
/// node's parameters only, others are left to the parameter store): each value must be of the
/// right type and range, and if a model parameter or `command_joints` is among them, all the
/// values together must give a usable model from the source they leave in force (the
/// `robot_description` parameter, `urdf_file`, the topic's `description`, or the default). A
/// `urdf_file` set while a `robot_description` shadows it must give a usable model too: it is
/// the source once `robot_description` is emptied.
pub fn validate_parameters<'a>(
    settings: &Mutex<Settings>,
    description: &Mutex<Option<String>>,
    values: impl IntoIterator<Item = (&'a str, &'a ParameterValue)>,
) -> Result<(), String> {
    let mut candidate = settings.lock().map_err(|e| e.to_string())?.clone();
    let (mut rebuilds, mut sets_file) = (false, false);
    for (name, value) in values {
        if !params::NAMES.contains(&name) {
            continue;
        }
        candidate.set(name, value)?;
        rebuilds |= params::MODEL_PARAMETERS.contains(&name) || name == "command_joints";
        sets_file |= name == "urdf_file";
    }
    if !rebuilds {
        return Ok(());
    }
    let description = description.lock().map_err(|e| e.to_string())?.clone();
    // Choosing a method never fails (auto falls back to aba), so the candidate skips auto's
    // measurements: the change that follows measures once, for real.
    candidate.method = Some(ForwardDynamicsMethod::Aba);
    Engine::from_settings(&candidate, description.as_deref())?;
    if sets_file && !candidate.robot_description.is_empty() && !candidate.urdf_file.is_empty() {
        let file = Settings {
            robot_description: String::new(),
            ..candidate
        };
        Engine::from_settings(&file, description.as_deref())
            .map_err(|e| format!("urdf_file (the source once robot_description is empty): {e}"))?;
    }
    Ok(())
}

/// Stores an accepted value of parameter `name`; true if it changed the value in force (the
/// change then takes effect through [`NodeState::parameter_changed`]).
pub fn apply_parameter(
    settings: &Mutex<Settings>,
    name: &str,
    value: &ParameterValue,
) -> Result<bool, String> {
    if !params::NAMES.contains(&name) {
        return Ok(false);
    }
    let mut settings = settings.lock().map_err(|e| e.to_string())?;
    if settings.get(name).as_ref() == Some(value) {
        return Ok(false);
    }
    settings.set(name, value)?;
    Ok(true)
}

impl NodeState {
    /// Parameter `name` changed: `method` chooses the method again, `publish_clock` is read at
    /// each tick, the clock parameters set the stamp policy, and any other rebuilds the engine
    /// (a model that cannot be rebuilt is logged as an error and the old one kept). Errors only
    /// if the shared settings are unreadable (a poisoned lock). The caller makes the
    /// simulation's timer again ([`super::simulation_timer`]): the engine may be new.
    pub fn parameter_changed(&mut self, name: &str) -> Result<(), String> {
        let settings = self.current_settings()?;
        if name == "method" {
            self.engine.set_method(settings.method);
        } else if name == "publish_clock" {
            // Read at each simulation tick.
        } else if params::TIME_PARAMETERS.contains(&name) {
            self.clock.configure(&settings);
        } else {
            let description = self
                .topic_description
                .lock()
                .map_err(|e| e.to_string())?
                .clone();
            match Engine::from_settings(&settings, description.as_deref()) {
                Ok(new) => self.replace_engine(new),
                Err(e) => log!(
                    self.logger,
                    Error,
                    "parameter '{name}' was accepted but the model could not be rebuilt, keeping robot '{}': {e}",
                    self.engine.model.name()
                ),
            }
        }
        log!(self.logger, Info, "parameter '{name}' now in effect");
        Ok(())
    }

    /// `use_sim_time` as the parameter store holds it (ros2-client keeps that parameter to
    /// itself: the node reads it before each use): on a change, the node's clock switches
    /// source and the change is logged.
    pub fn follow_use_sim_time(&mut self, wanted: bool) {
        if wanted == self.clock.use_sim_time() {
            return;
        }
        self.clock.set_use_sim_time(wanted);
        if let Ok(mut settings) = self.settings.lock() {
            settings.use_sim_time = wanted;
        }
        log!(
            self.logger,
            Info,
            "parameter 'use_sim_time' now in effect: {wanted}; the node's clock is the {}",
            clock::source_name(wanted, self.engine.simulated_time().is_some())
        );
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use crate::node::logging::Level;
    use crate::ros::msgs::{Header, JointState, Odometry, Quaternion};
    use spatial_dynamics_core::model::examples::PARTICLE_URDF;

    const THETA: f64 = 0.6;

    fn gravity_effort(state: &mut NodeState) -> f64 {
        let out = state.joint_states(Ok(pendulum_state(THETA, 0.0, at(1))), Some(0));
        out.gravity.expect("gravity effort").effort[0]
    }

    #[test]
    fn values_are_checked_against_the_model_they_would_build() {
        let state = serving(pendulum());
        let (settings, description) = (state.settings(), state.topic_description());
        let check = |name: &str, value: ParameterValue| {
            validate_parameter(&settings, &description, name, &value)
        };
        assert!(check("method", ParameterValue::String("crba".into())).is_ok());
        assert!(check("method", ParameterValue::String("fast".into())).is_err());
        let gravity = check("gravity", ParameterValue::DoubleArray(vec![0.0, 1.0]));
        assert!(gravity.unwrap_err().contains("gravity"));
        let urdf = check("robot_description", ParameterValue::String("<robot".into()));
        assert!(urdf.is_err());
        let joints = check(
            "command_joints",
            ParameterValue::StringArray(vec!["elbow".into()]),
        );
        assert!(joints.unwrap_err().contains("unknown joint 'elbow'"));
        assert!(check(
            "command_joints",
            ParameterValue::StringArray(vec!["joint1".into()])
        )
        .is_ok());
        // Not ours: left to the parameter store.
        assert!(check("qos_overrides", ParameterValue::Boolean(true)).is_ok());
        // Checking changes nothing.
        assert_eq!(settings.lock().unwrap().method, None);
    }

    #[test]
    fn a_stored_value_reports_whether_it_changed_anything() {
        let state = serving(pendulum());
        let settings = state.settings();
        let crba = ParameterValue::String("crba".into());
        assert_eq!(apply_parameter(&settings, "method", &crba), Ok(true));
        assert_eq!(apply_parameter(&settings, "method", &crba), Ok(false));
        assert_eq!(
            settings.lock().unwrap().method,
            Some(ForwardDynamicsMethod::Crba)
        );
        assert_eq!(apply_parameter(&settings, "not_ours", &crba), Ok(false));
    }

    #[test]
    fn parameter_changes_take_effect() {
        let mut state = serving(pendulum());
        assert_close(gravity_effort(&mut state), pendulum_gravity(THETA));
        let settings = state.settings();
        // Gravity enters the gravity effort linearly: doubling it doubles the effort.
        let doubled = ParameterValue::DoubleArray(vec![0.0, 0.0, -2.0 * G]);
        assert!(apply_parameter(&settings, "gravity", &doubled).unwrap());
        state.parameter_changed("gravity").unwrap();
        assert_close(gravity_effort(&mut state), 2.0 * pendulum_gravity(THETA));

        let crba = ParameterValue::String("crba".into());
        apply_parameter(&settings, "method", &crba).unwrap();
        state.parameter_changed("method").unwrap();
        assert_eq!(state.engine.method, ForwardDynamicsMethod::Crba);

        // The stamp policy: a stamp 2 s old passes, then fails once max_stamp_age is 1 s.
        let now = Some(10_000_000_000);
        let old = || Ok(pendulum_state(THETA, 0.0, at(8)));
        assert!(state.joint_states(old(), now).gravity.is_some());
        apply_parameter(&settings, "max_stamp_age", &ParameterValue::Double(1.0)).unwrap();
        state.parameter_changed("max_stamp_age").unwrap();
        assert!(state.joint_states(old(), now).gravity.is_none());

        // A model parameter rebuilds the model: a new description replaces the pendulum.
        let particle = ParameterValue::String(PARTICLE_URDF.into());
        apply_parameter(&settings, "robot_description", &particle).unwrap();
        state.parameter_changed("robot_description").unwrap();
        assert_eq!(state.engine.model.name(), "particle");
        let infos = logged(&state, Level::Info);
        assert!(infos.contains(&"parameter 'robot_description' now in effect".to_string()));
    }

    /// A rebuilt model takes over, by joint name, the latest effort command and the base state
    /// from `~/base_state`; what it has no place for is logged, and the residual the old model
    /// still owed is counted dropped on `~/effort_residual`.
    #[test]
    fn a_rebuilt_model_takes_over_the_command_and_the_base_state() {
        let arm = |gravity: f64, floating_base: bool| Settings {
            gravity: [0.0, 0.0, -gravity],
            floating_base,
            ..Settings::default()
        };
        let mut state = serving(arm(G, true));
        let names: Vec<String> = (1..=7).map(|k| format!("joint{k}")).collect();
        let joint_state = |sec: i32, effort: Vec<f64>| JointState {
            header: Header {
                stamp: at(sec),
                frame_id: String::new(),
            },
            name: names.clone(),
            position: vec![0.3, -0.5, 0.2, 1.1, -0.4, 0.6, 0.1],
            velocity: vec![0.0; 7],
            effort,
        };
        let gravity = |state: &mut NodeState, sec: i32| {
            let out = state.joint_states(Ok(joint_state(sec, Vec::new())), Some(0));
            (out.gravity.unwrap().effort, out.acceleration.unwrap())
        };
        // The base turned 0.4 rad about x turns the arm against gravity.
        let (s, c) = (0.2f64.sin(), 0.2f64.cos());
        let mut odometry = Odometry::default();
        odometry.pose.pose.orientation = Quaternion {
            x: s,
            y: 0.0,
            z: 0.0,
            w: c,
        };
        state.base_state(Ok(odometry));
        let command = JointState {
            name: names.clone(),
            effort: vec![0.0, 1.5, 0.0, 0.0, 0.0, 0.0, 0.0],
            ..Default::default()
        };
        state.effort_command(Ok(command));
        let (turned, _) = gravity(&mut state, 1);
        let (upright, _) = gravity(&mut serving(arm(G, true)), 1);
        assert!(
            (turned[1] - upright[1]).abs() > 0.1,
            "{turned:?} {upright:?}"
        );
        state.joint_states(Ok(joint_state(2, vec![0.3; 7])), Some(0));
        assert_eq!(state.health.total_dropped(), 0);

        let doubled = ParameterValue::DoubleArray(vec![0.0, 0.0, -2.0 * G]);
        apply_parameter(&state.settings(), "gravity", &doubled).unwrap();
        state.parameter_changed("gravity").unwrap();
        let reason = "the model changed before the next joint state: no residual for the joint \
                      state stamped 2.000000000";
        assert_eq!(state.health.dropped_on(&state.names.residual, reason), 1);
        let (effort, acceleration) = gravity(&mut state, 3);
        for (e, t) in effort.iter().zip(&turned) {
            assert_close(*e, 2.0 * t);
        }
        let joint2 = acceleration
            .name
            .iter()
            .position(|n| n == "joint2")
            .unwrap();
        assert_eq!(acceleration.effort[joint2], 1.5);
        let replaced = |state: &NodeState| {
            let warnings = logged(state, Level::Warn).into_iter();
            warnings
                .filter(|l| l.starts_with("robot "))
                .collect::<Vec<_>>()
        };
        assert!(replaced(&state).is_empty());

        // Without a floating base the base state has no place: said so.
        let fixed = ParameterValue::Boolean(false);
        apply_parameter(&state.settings(), "floating_base", &fixed).unwrap();
        state.parameter_changed("floating_base").unwrap();
        assert_eq!(
            replaced(&state),
            [
                "robot 'sd_arm7' replaces robot 'sd_arm7' without the base pose and twist \
              from ~/base_state (no floating base now)"
            ]
        );
        let (effort, acceleration) = gravity(&mut state, 4);
        let (want, _) = gravity(&mut serving(arm(2.0 * G, false)), 4);
        assert_eq!(effort, want);
        assert_eq!(acceleration.effort[joint2], 1.5);
    }

    #[test]
    fn a_model_that_cannot_be_rebuilt_is_logged_and_the_old_one_kept() {
        let mut state = serving(pendulum());
        // Stored without the validator (as a value valid alone, unusable with this model).
        state.settings().lock().unwrap().root_link = "no_such_link".into();
        state.parameter_changed("root_link").unwrap();
        assert_eq!(state.engine.model.name(), "pendulum1");
        let errors = logged(&state, Level::Error);
        assert_eq!(errors.len(), 1, "{errors:?}");
        assert!(errors[0].starts_with("parameter 'root_link' was accepted but the model could not be rebuilt, keeping robot 'pendulum1'"));
    }

    #[test]
    fn use_sim_time_switches_the_clock_once_and_says_so() {
        let mut state = serving(pendulum());
        state.follow_use_sim_time(false);
        assert!(logged(&state, Level::Info).is_empty());
        state.follow_use_sim_time(true);
        state.follow_use_sim_time(true);
        assert!(state.clock.use_sim_time());
        assert!(state.settings().lock().unwrap().use_sim_time);
        assert_eq!(
            logged(&state, Level::Info),
            ["parameter 'use_sim_time' now in effect: true; the node's clock is the /clock (use_sim_time)"]
        );
        // Simulated time: no /clock yet, then the first one.
        let out = state.joint_states(Ok(pendulum_state(THETA, 0.0, at(1))), None);
        assert!(out.gravity.is_none());
        state.clock_received(&at(5));
        let now = state.clock.now(std::time::SystemTime::now(), None);
        assert_eq!(now, Some(5_000_000_000));
        let out = state.joint_states(Ok(pendulum_state(THETA, 0.0, at(1))), now);
        assert_eq!(out.gravity.unwrap().header.stamp, at(5));
        // Two /clock sources interleaved: time goes back every other message, noted once a
        // second.
        for k in 0..20 {
            state.clock_received(&at(if k % 2 == 0 { 3 } else { 9 }));
        }
        let notes = logged(&state, Level::Info);
        let back: Vec<_> = notes.iter().filter(|l| l.contains("went back")).collect();
        assert_eq!(back.len(), 1, "{back:?}");
    }
}
