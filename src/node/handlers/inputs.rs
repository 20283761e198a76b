//! The subscribed topics: each handler takes the decoded message (or why it could not be
//! decoded) and, for inputs that stamp outputs, the node's time when it arrived (ns; `None`
//! while simulated time has not arrived), and returns what to publish.

use super::{checked, NodeState, Outputs};
use crate::node::engine::{Engine, ModelSource};
use crate::node::logging::log;
use crate::ros::msgs::*;
use std::time::Instant;

impl NodeState {
    /// `joint_states` → `~/gravity_effort`, `~/acceleration` and the previous joint state's
    /// `~/effort_residual` ([`Engine::joint_states`]), after the stamp policy admits it
    /// ([`crate::node::engine::clock::NodeClock::admit`]). A refused message is counted on
    /// `joint_states`; a refused effort (and a residual that could not be formed) on
    /// `~/effort_residual`.
    pub fn joint_states(
        &mut self,
        message: Result<JointState, String>,
        now: Option<i64>,
    ) -> Outputs {
        self.health.received(&self.names.joint_states);
        let started = Instant::now();
        let answer = message.and_then(|js| {
            let stamp = self.clock.admit(&js.header.stamp, now)?;
            self.engine.joint_states(&js, stamp)
        });
        let mut out = Outputs::default();
        match answer {
            Ok(answer) => {
                self.health.computed(started.elapsed());
                out.gravity = checked(&mut self.health, answer.gravity, &self.names.gravity);
                out.acceleration = checked(
                    &mut self.health,
                    answer.acceleration,
                    &self.names.acceleration,
                );
                match answer.residual {
                    Some(Ok(r)) => {
                        out.residual = checked(&mut self.health, r, &self.names.residual)
                    }
                    Some(Err(e)) => self.health.dropped(&self.names.residual, &e),
                    None => {}
                }
                if let Some(e) = answer.bad_effort {
                    self.health.dropped(&self.names.residual, &e);
                }
            }
            Err(e) => self.health.dropped(&self.names.joint_states, &e),
        }
        out
    }

    /// `~/effort_command`: the effort to apply from now on, by joint name.
    pub fn effort_command(&mut self, message: Result<JointState, String>) {
        self.health.received(&self.names.effort_command);
        if let Err(e) = message.and_then(|m| self.engine.set_effort_command(&m)) {
            self.health.dropped(&self.names.effort_command, &e);
        }
    }

    /// `~/commands`: the effort to apply from now on, in `command_joints` order.
    pub fn commands(&mut self, message: Result<Float64MultiArray, String>) {
        self.health.received(&self.names.commands);
        if let Err(e) = message.and_then(|m| self.engine.set_commands(&m)) {
            self.health.dropped(&self.names.commands, &e);
        }
    }

    /// `~/base_state`: the floating base's pose and twist for the topic inputs.
    pub fn base_state(&mut self, message: Result<Odometry, String>) {
        self.health.received(&self.names.base_state);
        if let Err(e) = message.and_then(|m| self.engine.set_base_state(&m)) {
            self.health.dropped(&self.names.base_state, &e);
        }
    }

    /// `~/reference` → `~/feedforward_effort` (stamped by the node's clock policy) and
    /// `~/feedforward_commands` ([`Engine::reference`]).
    pub fn reference(
        &mut self,
        message: Result<JointTrajectory, String>,
        now: Option<i64>,
    ) -> Outputs {
        self.health.received(&self.names.reference);
        let started = Instant::now();
        let answer = message.and_then(|m| {
            let stamp = self.clock.output_stamp(&m.header.stamp, now)?;
            let (mut effort, commands) = self.engine.reference(&m)?;
            effort.header.stamp = stamp;
            Ok((effort, commands))
        });
        let mut out = Outputs::default();
        match answer {
            Ok((effort, commands)) => {
                self.health.computed(started.elapsed());
                out.feedforward_effort =
                    checked(&mut self.health, effort, &self.names.feedforward_effort);
                out.feedforward_commands =
                    checked(&mut self.health, commands, &self.names.feedforward_commands);
            }
            Err(e) => self.health.dropped(&self.names.reference, &e),
        }
        out
    }

    /// `robot_description` (the topic): the model is rebuilt from it when neither the
    /// `robot_description` parameter nor `urdf_file` is set (they win over the topic; why it
    /// is ignored is logged once per reason). An unusable description is counted and the model
    /// kept. Errors only if the shared settings are unreadable (a poisoned lock).
    pub fn robot_description(&mut self, message: Result<StringMsg, String>) -> Result<(), String> {
        let topic = self.names.robot_description.clone();
        self.health.received(&topic);
        let text = match message {
            Ok(m) => m.data,
            Err(e) => {
                self.health.dropped(&topic, &e);
                return Ok(());
            }
        };
        let settings = self.current_settings()?;
        let new = match Engine::from_settings(&settings, Some(&text)) {
            Ok(new) => new,
            Err(e) => {
                let why = format!(
                    "unusable robot description, keeping robot '{}': {e}",
                    self.engine.model.name
                );
                self.health.dropped(&topic, &why);
                return Ok(());
            }
        };
        *self.topic_description.lock().map_err(|e| e.to_string())? = Some(text);
        if new.source == ModelSource::Topic {
            log!(
                self.logger,
                Info,
                "loaded robot '{}' from {topic}",
                new.model.name
            );
            self.engine = new;
            return Ok(());
        }
        let why = match &new.source {
            ModelSource::Parameter => "the robot_description parameter is set".to_string(),
            ModelSource::File(f) => format!("urdf_file is set ({f})"),
            _ => "another source is in use".to_string(),
        };
        if self.ignored_description.as_ref() != Some(&why) {
            log!(self.logger, Info, "ignoring the robot description on {topic}: {why}, and it wins over the topic (the topic's description is used once neither robot_description nor urdf_file is set)");
            self.ignored_description = Some(why);
        }
        Ok(())
    }

    /// A `/clock` message taking effect (`use_sim_time`, serve mode): its time becomes the
    /// node's; time going back (a bag looped) is logged.
    pub fn clock_received(&mut self, t: &Time) {
        if let Some(note) = self.clock.clock_received(t) {
            log!(self.logger, Info, "{note}");
        }
    }
}
