//! The subscribed topics: each handler takes the decoded message (or why it could not be
//! decoded) and, for inputs that stamp outputs, the node's time when it arrived (ns; `None`
//! while simulated time has not arrived), and returns what to publish.

use super::{checked, NodeState, Outputs};
use crate::node::engine::{Engine, ModelSource};
use crate::node::logging::log;
use crate::ros::msgs::*;
use std::time::{Duration, Instant};

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

    /// `~/effort_command`: the effort to apply from now on, by joint name (with servos, their
    /// feed-forward).
    pub fn effort_command(&mut self, message: Result<JointState, String>) -> Outputs {
        let accepted = message.and_then(|m| {
            self.engine.command_can_step()?;
            self.engine.set_effort_command(&m)
        });
        let topic = self.names.effort_command.clone();
        self.command_received(&topic, accepted)
    }

    /// `~/commands`: the command from now on, in `command_joints` order, per
    /// `command_interface` (efforts, or the servos' position or velocity targets).
    pub fn commands(&mut self, message: Result<Float64MultiArray, String>) -> Outputs {
        let accepted = message.and_then(|m| {
            self.engine.command_can_step()?;
            self.engine.set_commands(&m)
        });
        let topic = self.names.commands.clone();
        self.command_received(&topic, accepted)
    }

    /// `~/joint_commands`: the command from now on by joint name, the field of
    /// `command_interface` ([`Engine::set_joint_commands`]).
    pub fn joint_commands(&mut self, message: Result<JointState, String>) -> Outputs {
        let accepted = message.and_then(|m| {
            self.engine.command_can_step()?;
            self.engine.set_joint_commands(&m)
        });
        let topic = self.names.joint_commands.clone();
        self.command_received(&topic, accepted)
    }

    /// A command on `topic`, counted; a refused one dropped with its reason. With
    /// `step_mode: on_command` an accepted one advances the simulation, whose state goes out.
    fn command_received(&mut self, topic: &str, accepted: Result<(), String>) -> Outputs {
        self.health.received(topic);
        match accepted {
            Ok(()) => {
                let step = self.engine.command_step(Instant::now());
                self.simulation_outputs(step)
            }
            Err(e) => {
                self.health.dropped(topic, &e);
                Outputs::default()
            }
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
    /// is ignored is logged once per reason, and the description is kept for when neither is
    /// set any more). A description that could not serve, now or then, is counted and not
    /// kept, and the model stays. Errors only if the shared settings are unreadable (a poisoned
    /// lock).
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
                    self.engine.model.name()
                );
                self.health.dropped(&topic, &why);
                return Ok(());
            }
        };
        if new.source != ModelSource::Topic {
            // Kept for when neither the parameter nor urdf_file is set: usable then too.
            let mut topic_only = settings.clone();
            (topic_only.robot_description, topic_only.urdf_file) = (String::new(), String::new());
            if let Err(e) = Engine::from_settings(&topic_only, Some(&text)) {
                let why = format!("unusable robot description (not kept for later): {e}");
                self.health.dropped(&topic, &why);
                return Ok(());
            }
        }
        *self.topic_description.lock().map_err(|e| e.to_string())? = Some(text);
        if new.source == ModelSource::Topic {
            log!(
                self.logger,
                Info,
                "loaded robot '{}' from {topic}",
                new.model.name()
            );
            self.replace_engine(new);
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
    /// node's; time going back (a bag looped) is logged, at most once a second.
    pub fn clock_received(&mut self, t: &Time) {
        let Some(note) = self.clock.clock_received(t) else {
            return;
        };
        let (last, since) = &mut self.clock_went_back;
        let now = Instant::now();
        if last.is_some_and(|at| now.duration_since(at) < Duration::from_secs(1)) {
            *since += 1;
            return;
        }
        let more = match std::mem::take(since) {
            0 => String::new(),
            n => format!(" ({n} more times since the last note)"),
        };
        *last = Some(now);
        log!(self.logger, Info, "{note}{more}");
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use crate::node::logging::Level;
    use crate::node::params::Settings;
    use spatial_dynamics_core::model::examples::{pendulum_urdf, PARTICLE_URDF};

    const THETA: f64 = 0.7;

    #[test]
    fn a_joint_state_gives_the_closed_form_gravity_effort_and_acceleration_with_its_stamp() {
        let mut state = serving(pendulum());
        let out = state.joint_states(Ok(pendulum_state(THETA, 0.3, at(42))), Some(0));
        let gravity = out.gravity.expect("gravity effort");
        assert_eq!(gravity.header.stamp, at(42));
        assert_eq!(gravity.header.frame_id, "base");
        assert_eq!(gravity.name, ["joint1"]);
        assert_close(gravity.effort[0], pendulum_gravity(THETA));
        // No command yet: the pendulum swings freely (the velocity adds no torque about a
        // fixed axis).
        let acceleration = out.acceleration.expect("acceleration");
        assert_close(
            acceleration.acceleration[0],
            -pendulum_gravity(THETA) / pendulum_inertia(),
        );
        assert!(out.residual.is_none() && out.feedforward_effort.is_none());
        assert_eq!(state.health.received_on("/joint_states"), 1);
        assert_eq!(state.health.total_dropped(), 0);
    }

    #[test]
    fn an_effort_command_enters_the_acceleration_and_a_bad_one_is_counted() {
        let mut state = serving(pendulum());
        let command = |effort: Vec<f64>| JointState {
            name: vec!["joint1".into()],
            effort,
            ..Default::default()
        };
        state.effort_command(Ok(command(vec![1.5])));
        let out = state.joint_states(Ok(pendulum_state(THETA, 0.0, at(1))), Some(0));
        let a = out.acceleration.unwrap();
        assert_close(a.effort[0], 1.5);
        assert_close(
            a.acceleration[0],
            (1.5 - pendulum_gravity(THETA)) / pendulum_inertia(),
        );
        state.effort_command(Ok(command(vec![1.0, 2.0])));
        state.effort_command(Err("unreadable message: x".into()));
        state.commands(Ok(Float64MultiArray {
            data: vec![f64::NAN],
            ..Default::default()
        }));
        let names = state.names.clone();
        assert_eq!(state.health.received_on(&names.effort_command), 3);
        assert_eq!(state.health.total_dropped(), 3);
        let unreadable = state
            .health
            .dropped_on(&names.effort_command, "unreadable message: x");
        assert_eq!(unreadable, 1);
        // The refused commands left the good one in force.
        let out = state.joint_states(Ok(pendulum_state(THETA, 0.0, at(2))), Some(0));
        assert_close(out.acceleration.unwrap().effort[0], 1.5);
    }

    #[test]
    fn commands_in_command_joint_order_set_the_effort() {
        let mut state = serving(Settings {
            robot_description: PARTICLE_URDF.into(),
            command_joints: vec!["z".into(), "x".into()],
            ..Settings::default()
        });
        state.commands(Ok(Float64MultiArray {
            data: vec![G, 2.0],
            ..Default::default()
        }));
        let js = JointState {
            name: vec!["x".into(), "z".into()],
            position: vec![0.0, 0.0],
            velocity: vec![0.0, 0.0],
            ..Default::default()
        };
        // The particle (1 kg): ẍ = 2, and z̈ = 0 with its weight carried by the command.
        let a = state.joint_states(Ok(js), Some(0)).acceleration.unwrap();
        assert_close(a.acceleration[0], 2.0);
        assert_close(a.acceleration[1], 0.0);
    }

    #[test]
    fn a_bad_joint_state_is_dropped_counted_and_warned_about_once_a_second() {
        let mut state = serving(pendulum());
        let mut unknown = pendulum_state(THETA, 0.0, at(1));
        unknown.name = vec!["elbow".into()];
        for _ in 0..3 {
            let out = state.joint_states(Ok(unknown.clone()), Some(0));
            assert!(out.gravity.is_none() && out.acceleration.is_none());
        }
        assert_eq!(
            state
                .health
                .dropped_on("/joint_states", "unknown joint 'x'"),
            3
        );
        let warnings = logged(&state, Level::Warn);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].starts_with("dropped a message on /joint_states: unknown joint 'elbow'"),
            "{}",
            warnings[0]
        );
        std::thread::sleep(std::time::Duration::from_millis(1010));
        state.joint_states(Err("unreadable message: truncated".into()), Some(0));
        let warnings = logged(&state, Level::Warn);
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings[1]
                .ends_with("unreadable message: truncated (2 more dropped since the last warning)"),
            "{}",
            warnings[1]
        );
    }

    #[test]
    fn a_state_whose_dynamics_overflow_is_dropped_with_the_reason() {
        // A rate of 1e200 rad/s is finite, but a double pendulum's first link spinning at it
        // pulls the second, bent at THETA, with a centrifugal torque of order m l² ω² ≈ 1e400:
        // its acceleration is not finite.
        let mut state = serving(Settings {
            robot_description: pendulum_urdf(2, LENGTH, MASS),
            ..Settings::default()
        });
        let message = JointState {
            name: vec!["joint1".into(), "joint2".into()],
            position: vec![THETA, THETA],
            velocity: vec![1e200, 0.0],
            ..pendulum_state(THETA, 0.0, at(1))
        };
        let out = state.joint_states(Ok(message), Some(0));
        assert!(out.gravity.is_none() && out.acceleration.is_none());
        let status = state.health.report("test", "pendulum1", true);
        let dropped: Vec<_> = status
            .values
            .iter()
            .filter(|v| v.key.contains("dropped"))
            .collect();
        assert_eq!(dropped.len(), 1, "{dropped:?}");
        assert!(
            dropped[0].key.starts_with("/joint_states dropped: "),
            "{dropped:?}"
        );
        assert_eq!(dropped[0].value, "1");
    }

    #[test]
    fn stamps_outside_the_policy_are_dropped_and_simulated_time_waits_for_clock() {
        let mut state = serving(Settings {
            max_stamp_age: 1.0,
            ..pendulum()
        });
        let now = 100_000_000_000; // 100 s
        let fresh = state.joint_states(Ok(pendulum_state(THETA, 0.0, at(99))), Some(now));
        assert!(fresh.gravity.is_some());
        let stale = state.joint_states(Ok(pendulum_state(THETA, 0.0, at(98))), Some(now));
        assert!(stale.gravity.is_none());
        let dropped = state.health.dropped_on("/joint_states", "stale stamp (x)");
        assert_eq!(dropped, 1);
        state.follow_use_sim_time(true);
        let reference = JointTrajectory {
            joint_names: vec!["joint1".into()],
            points: vec![JointTrajectoryPoint {
                positions: vec![THETA],
                ..Default::default()
            }],
            ..Default::default()
        };
        let out = state.reference(Ok(reference), None);
        assert!(out.feedforward_effort.is_none());
        let topic = "/spatial_dynamics/reference";
        let waiting = state.health.dropped_on(topic, "waiting for /clock (x)");
        assert_eq!(waiting, 1);
    }

    #[test]
    fn a_reference_gives_the_inverse_dynamics_of_its_first_point() {
        let mut state = serving(pendulum());
        let (theta, rate, accel) = (-0.4, 2.0, 3.0);
        let reference = JointTrajectory {
            header: Header {
                stamp: at(7),
                frame_id: String::new(),
            },
            joint_names: vec!["joint1".into()],
            points: vec![JointTrajectoryPoint {
                positions: vec![theta],
                velocities: vec![rate],
                accelerations: vec![accel],
                ..Default::default()
            }],
        };
        let out = state.reference(Ok(reference), Some(0));
        let expected = pendulum_inertia() * accel + pendulum_gravity(theta);
        let effort = out.feedforward_effort.unwrap();
        assert_eq!(effort.header.stamp, at(7));
        assert_close(effort.effort[0], expected);
        assert_close(out.feedforward_commands.unwrap().data[0], expected);
        let empty = state.reference(Ok(JointTrajectory::default()), Some(0));
        assert!(empty.feedforward_effort.is_none() && empty.feedforward_commands.is_none());
        let reason = "the reference trajectory has no points";
        let dropped = state
            .health
            .dropped_on("/spatial_dynamics/reference", reason);
        assert_eq!(dropped, 1);
    }

    #[test]
    fn a_base_state_for_a_fixed_base_is_dropped() {
        let mut state = serving(pendulum());
        state.base_state(Ok(Odometry::default()));
        let reason = "the model has no floating base";
        let dropped = state
            .health
            .dropped_on("/spatial_dynamics/base_state", reason);
        assert_eq!(dropped, 1);
    }

    #[test]
    fn robot_description_reloads_the_model_unless_a_parameter_wins() {
        let mut state = serving(Settings::default());
        let text = |s: &str| Ok(StringMsg { data: s.into() });
        state.robot_description(text(PARTICLE_URDF)).unwrap();
        assert_eq!(state.engine.model.name(), "particle");
        assert_eq!(state.engine.source, ModelSource::Topic);
        // The particle's weight, m g on z.
        let js = JointState {
            name: vec!["x".into(), "z".into()],
            position: vec![0.0, 0.0],
            ..Default::default()
        };
        let gravity = state.joint_states(Ok(js), Some(0)).gravity.unwrap();
        assert_close(gravity.effort[1], G);
        state
            .robot_description(text("<robot name='broken'>"))
            .unwrap();
        assert_eq!(state.engine.model.name(), "particle");
        let reason = "unusable robot description, keeping robot 'particle'";
        assert_eq!(state.health.dropped_on("/robot_description", reason), 1);
        // With the robot_description parameter set, the topic is ignored, said once.
        let mut state = serving(pendulum());
        state.robot_description(text(PARTICLE_URDF)).unwrap();
        state.robot_description(text(PARTICLE_URDF)).unwrap();
        assert_eq!(state.engine.model.name(), "pendulum1");
        let ignoring = "ignoring the robot description on /robot_description: the robot_description parameter is set";
        let said = logged(&state, Level::Info);
        assert_eq!(said.iter().filter(|l| l.starts_with(ignoring)).count(), 1);
        // Kept for when the parameter is cleared.
        let kept = state.topic_description().lock().unwrap().clone();
        assert_eq!(kept.as_deref(), Some(PARTICLE_URDF));
        // An unusable one is counted, not kept: the kept one stays.
        state
            .robot_description(text("<robot name='broken'>"))
            .unwrap();
        let reason = "unusable robot description (not kept for later)";
        assert_eq!(state.health.dropped_on("/robot_description", reason), 1);
        let kept = state.topic_description().lock().unwrap().clone();
        assert_eq!(kept.as_deref(), Some(PARTICLE_URDF));
        assert_eq!(state.engine.model.name(), "pendulum1");
    }
}

#[cfg(test)]
mod command_interface_tests {
    use super::super::test_support::*;
    use super::*;
    use crate::node::params::Settings;
    use spatial_dynamics_core::model::examples::PARTICLE_URDF;
    use spatial_dynamics_core::sim::CommandInterface;

    /// The particle (1 kg on joints x, z) simulated in 1 ms steps, commands stepping it.
    fn lockstep(interface: CommandInterface, steps_per_command: usize) -> NodeState {
        serving(Settings {
            robot_description: PARTICLE_URDF.into(),
            simulate: true,
            command_interface: interface,
            servo_kp: vec![400.0],
            servo_kd: vec![40.0],
            lockstep: true,
            steps_per_command,
            ..Settings::default()
        })
    }

    fn by_name(names: &[&str], position: &[f64], velocity: &[f64]) -> JointState {
        JointState {
            name: names.iter().map(|n| n.to_string()).collect(),
            position: position.to_vec(),
            velocity: velocity.to_vec(),
            ..Default::default()
        }
    }

    #[test]
    fn each_command_advances_exactly_steps_per_command_and_publishes_once() {
        let mut state = lockstep(CommandInterface::Effort, 3);
        assert!(state.simulation_tick_now().joint_states.is_none());
        let mut ns = 0;
        for _ in 0..4 {
            let out = state.commands(Ok(Float64MultiArray {
                data: vec![0.0, G],
                ..Default::default()
            }));
            ns += 3_000_000;
            let js = out.joint_states.expect("a joint state per command");
            assert_eq!(
                js.header.stamp,
                crate::node::engine::clock::time_from_nanos(ns)
            );
            // The weight carried: the particle stays at rest.
            assert_eq!(js.position, [0.0, 0.0]);
        }
        // A refused command does not step.
        let out = state.commands(Ok(Float64MultiArray {
            data: vec![f64::NAN, 0.0],
            ..Default::default()
        }));
        assert!(out.joint_states.is_none());
        assert_close(state.engine.simulated_time().unwrap(), 0.012);
    }

    #[test]
    fn a_position_servo_holds_the_particle_short_by_m_g_over_kp() {
        let mut state = lockstep(CommandInterface::Position, 100);
        let mut last = None;
        for _ in 0..30 {
            last = state
                .joint_commands(Ok(by_name(&["z", "x"], &[0.5, 0.2], &[])))
                .joint_states;
        }
        let js = last.unwrap();
        assert_close(js.position[0], 0.2);
        assert!(
            (js.position[1] - (0.5 - G / 400.0)).abs() < 1e-9,
            "{:?}",
            js.position
        );
        // The published effort is the servo's: the weight on z.
        assert!((js.effort[1] - G).abs() < 1e-6, "{:?}", js.effort);
    }

    #[test]
    fn a_velocity_servo_reaches_the_commanded_rate() {
        let mut state = lockstep(CommandInterface::Velocity, 100);
        let mut last = None;
        for _ in 0..10 {
            last = state
                .joint_commands(Ok(by_name(&["x"], &[], &[0.3])))
                .joint_states;
        }
        let js = last.unwrap();
        // v = 0.3 (1 − (1 − h kd/m)^n) with h kd = 0.04, n = 1000.
        assert!((js.velocity[0] - 0.3).abs() < 1e-12, "{:?}", js.velocity);
        // z never named: its rate target stays zero, and the servo's damping carries the weight
        // at the terminal rate −m g / kd.
        assert!(
            (js.velocity[1] + G / 40.0).abs() < 1e-9,
            "{:?}",
            js.velocity
        );
    }

    #[test]
    fn bad_joint_commands_are_dropped_counted_and_change_nothing() {
        let mut state = lockstep(CommandInterface::Position, 1);
        let topic = state.names.joint_commands.clone();
        let bad = [
            by_name(&["elbow"], &[0.1], &[]),
            by_name(&["x"], &[], &[0.1]),
            by_name(&["x"], &[f64::NAN], &[]),
            by_name(&["x", "x"], &[0.1, 0.2], &[]),
            by_name(&["x"], &[0.1], &[0.1, 0.2]),
        ];
        for message in bad {
            assert!(state.joint_commands(Ok(message)).joint_states.is_none());
        }
        assert_eq!(state.health.received_on(&topic), 5);
        assert_eq!(state.health.total_dropped(), 5);
        assert_eq!(state.health.dropped_on(&topic, "unknown joint 'x'"), 1);
        assert_eq!(state.engine.simulated_time(), Some(0.0));
        // ~/commands in position mode: one target per command joint.
        let wrong_length = Float64MultiArray {
            data: vec![0.1],
            ..Default::default()
        };
        assert!(state.commands(Ok(wrong_length)).joint_states.is_none());
        assert_eq!(state.health.total_dropped(), 6);
    }

    #[test]
    fn a_command_that_could_not_step_is_refused_while_paused_or_stopped() {
        let mut state = lockstep(CommandInterface::Effort, 1);
        let weight = || {
            Ok(Float64MultiArray {
                data: vec![0.0, G],
                ..Default::default()
            })
        };
        assert!(state.pause(&SetBoolRequest { data: true }).success);
        assert!(state.commands(weight()).joint_states.is_none());
        let paused = "step_mode on_command: the simulation is paused, a command would not step \
                      it (~/pause false resumes it)";
        let topic = state.names.commands.clone();
        assert_eq!(state.health.dropped_on(&topic, paused), 1);
        assert!(state.pause(&SetBoolRequest { data: false }).success);
        assert!(state.commands(weight()).joint_states.is_some());
        // Stopped: the largest effort drives the particle's state past the largest number
        // (without effort limits on), and the simulation stops.
        let huge = Ok(Float64MultiArray {
            data: vec![f64::MAX, 0.0],
            ..Default::default()
        });
        for _ in 0..10_000 {
            if state.commands(huge.clone()).joint_states.is_none() {
                break;
            }
        }
        let stopped = state.engine.command_can_step().unwrap_err();
        assert!(stopped.contains("simulation stopped"), "{stopped}");
        let before = state.health.total_dropped();
        assert!(state.commands(weight()).joint_states.is_none());
        assert_eq!(state.health.total_dropped(), before + 1);
    }

    #[test]
    fn a_joint_command_naming_no_joint_is_dropped() {
        let mut state = lockstep(CommandInterface::Position, 1);
        assert!(state
            .joint_commands(Ok(by_name(&[], &[], &[])))
            .joint_states
            .is_none());
        let reason = "the message names no joint: name the joints it commands";
        let topic = state.names.joint_commands.clone();
        assert_eq!(state.health.dropped_on(&topic, reason), 1);
        assert_eq!(state.engine.simulated_time(), Some(0.0));
    }

    #[test]
    fn the_published_effort_is_the_one_applied_after_the_limit() {
        // The particle's joints are limited to 100 N.
        let mut state = serving(Settings {
            robot_description: PARTICLE_URDF.into(),
            simulate: true,
            lockstep: true,
            passive: vec!["effort_limits".into()],
            ..Settings::default()
        });
        let js = state
            .commands(Ok(Float64MultiArray {
                data: vec![5000.0, -20.0],
                ..Default::default()
            }))
            .joint_states
            .unwrap();
        assert_eq!(js.effort, [100.0, -20.0]);
        // 100 N on 1 kg for one 1 ms step.
        assert_close(js.velocity[0], 0.1);
    }
}
