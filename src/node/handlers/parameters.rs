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
/// the parameter store): the value must be of the right type and range, and a value of a model
/// parameter or `command_joints` must give a usable model from the current source (the
/// `robot_description` parameter, `urdf_file`, the topic's `description`, or the default).
pub fn validate_parameter(
    settings: &Mutex<Settings>,
    description: &Mutex<Option<String>>,
    name: &str,
    value: &ParameterValue,
) -> Result<(), String> {
    if !params::NAMES.contains(&name) {
        return Ok(());
    }
    let mut candidate = settings.lock().map_err(|e| e.to_string())?.clone();
    candidate.set(name, value)?;
    if params::MODEL_PARAMETERS.contains(&name) || name == "command_joints" {
        let description = description.lock().map_err(|e| e.to_string())?.clone();
        // Choosing a method never fails (auto falls back to aba), so the candidate skips
        // auto's measurements: the change that follows measures once, for real.
        candidate.method = Some(ForwardDynamicsMethod::Aba);
        Engine::from_settings(&candidate, description.as_deref())?;
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
                Ok(new) => self.engine = new,
                Err(e) => log!(
                    self.logger,
                    Error,
                    "parameter '{name}' was accepted but the model could not be rebuilt, keeping robot '{}': {e}",
                    self.engine.model.name
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
