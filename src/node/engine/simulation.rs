//! Simulate mode: the engine owns the robot state and integrates it from the commands
//! (`~/commands`, `~/joint_commands`, `~/effort_command`). With `command_interface: effort` a
//! command is the joint effort; with `position` or `velocity` it is a servo target, and the
//! servo's effort ([`Servo`]) is formed from the state at every `sim_dt` step, with the effort
//! command added as a feed-forward. A command older than `command_timeout` (wall clock) drops
//! to zero effort, servos off. With `step_mode: free` the state advances
//! `real_time_factor × period` per tick of the publish timer, in steps of `sim_dt`; with
//! `on_command` each accepted command advances it by `steps_per_command` steps and nothing else
//! does (the wall-clock `command_timeout` does not apply: time only moves with commands). A
//! diverging integration stops the simulation (the last finite state stays, nothing non-finite
//! is published) and says when and why.

use super::requests::Refused;
use super::Engine;
use crate::joint_states::joint_map::Target;
use crate::node::params::{parse_passive, Settings};
use crate::ros::msgs::*;
use spatial_dynamics_core::error::{name_list, quoted};
use spatial_dynamics_core::sim::{CommandInterface, Servo, ServoAxis, SimConfig, Simulator, State};
use std::time::{Duration, Instant};

/// How far behind its due time a publish tick may run and still step: a tick later than this
/// many periods, and later than [`MIN_LAG`], is dropped and its steps counted as missed. Ticks
/// within it are run as soon as they can (the timer bursts), so a short stall of the process
/// costs no simulated time.
pub const MAX_LAG_TICKS: u32 = 10;

/// The shortest lag that drops a tick, whatever the period: the timer wakes the node with a
/// resolution of about a millisecond, so at periods of microseconds every tick runs a few
/// periods late even when the node keeps up.
pub const MIN_LAG: Duration = Duration::from_millis(20);

/// The most `sim_dt` steps one publish tick may ask for (`real_time_factor / (publish_rate ·
/// sim_dt)`), as `steps_per_command` is bounded: a tick runs its steps without yielding, so
/// more would hold the node's services and shutdown for seconds.
pub const MAX_STEPS_PER_TICK: f64 = 1e6;

/// The simulated robot.
pub struct Simulation {
    sim: Simulator,
    pub state: State,
    pub paused: bool,
    /// Why the simulation stopped, if it diverged.
    pub diverged: Option<String>,
    rate: f64,
    real_time_factor: f64,
    command_timeout: f64,
    /// Wall-clock and simulated time at the last rate measurement.
    measured_since: (Instant, f64),
    /// Simulated seconds per wall-clock second over the last report period.
    pub measured_rtf: f64,
    /// Wall time of the last publish tick that stepped, and how many stepping ticks came more
    /// than one period late (more than two periods after the tick before): a whole step slot
    /// missed. Paused, stopped or in lockstep the timer steps nothing and counts nothing.
    last_tick: Option<Instant>,
    late_ticks: u64,
    /// Steps dropped because their tick ran more than [`MAX_LAG_TICKS`] periods after it was
    /// due: simulated time the robot did not live in real time.
    missed_steps: u64,
    zero: Vec<f64>,
    /// Position or velocity servos on the command joints, axis `k` on `command_joints[k]`;
    /// none with `command_interface: effort`.
    servo: Option<Servo>,
    /// The effort of the current step (`nv`): the effort command plus the servos'.
    tau: Vec<f64>,
    /// That effort as the dynamics receive it (clamped to the URDF limits with
    /// `passive: effort_limits`): what `joint_states.effort` carries.
    applied: Vec<f64>,
    /// `sim_dt` steps owed to the publish timer, below one: `real_time_factor / (publish_rate ·
    /// sim_dt)` steps a tick, carried from tick to tick so the rate keeps to the factor.
    owed_steps: f64,
    /// `step_mode: on_command`: the steps each accepted command advances; `None`: free running.
    lockstep: Option<usize>,
    publish_tf: bool,
}

impl Simulation {
    /// The simulator stepping the state.
    pub(super) fn simulator(&self) -> &Simulator {
        &self.sim
    }
}

impl Engine {
    /// Starts simulating (simulate mode) from `initial_positions`, or stops (serve mode).
    pub(crate) fn configure_simulation(&mut self, settings: &Settings) -> Result<(), String> {
        if !settings.simulate {
            self.simulation = None;
            return Ok(());
        }
        let steps_per_tick = settings.real_time_factor / (settings.publish_rate * settings.sim_dt);
        // The three are positive and finite: the quotient is positive, or infinite.
        if steps_per_tick > MAX_STEPS_PER_TICK {
            return Err(format!(
                "real_time_factor / (publish_rate · sim_dt) = {steps_per_tick:.3e} steps of \
                 sim_dt per publish tick, more than {MAX_STEPS_PER_TICK:e}: raise sim_dt or \
                 publish_rate, or lower real_time_factor"
            ));
        }
        let config = SimConfig {
            integrator: settings.integrator,
            method: self.method,
            dt: settings.sim_dt,
            substeps: 1,
            passive: parse_passive(&settings.passive)?,
            ground: (!settings.ground.points.is_empty()).then(|| settings.ground.clone()),
        };
        let mut q = vec![0.0; self.model.nq()];
        if let Some((qi, _)) = self.map.base() {
            q[qi + 6] = 1.0;
        }
        for (name, value) in &settings.initial_positions {
            let index = self.map.index(name).ok_or_else(|| {
                format!(
                    "initial_positions: unknown joint {} (the model's joints: {})",
                    quoted(name),
                    name_list(self.map.names(), self.map.names().len())
                )
            })?;
            q[self.map.slot(index).0] = *value;
        }
        let servo = self.make_servo(settings)?;
        self.simulation = Some(Simulation {
            sim: Simulator::new(&self.model, config)?,
            state: State::at_rest(&self.model, q),
            paused: false,
            diverged: None,
            rate: settings.publish_rate,
            real_time_factor: settings.real_time_factor,
            command_timeout: settings.command_timeout,
            measured_since: (Instant::now(), 0.0),
            measured_rtf: 0.0,
            last_tick: None,
            late_ticks: 0,
            missed_steps: 0,
            zero: vec![0.0; self.model.nv()],
            servo,
            tau: vec![0.0; self.model.nv()],
            applied: vec![0.0; self.model.nv()],
            owed_steps: 0.0,
            lockstep: settings.lockstep.then_some(settings.steps_per_command),
            publish_tf: settings.publish_tf,
        });
        Ok(())
    }

    /// The servos of `command_interface` on the command joints, with `servo_kp`, `servo_kd`
    /// (one gain for all, or one per command joint).
    fn make_servo(&self, settings: &Settings) -> Result<Option<Servo>, String> {
        if settings.command_interface == CommandInterface::Effort {
            return Ok(None);
        }
        let names = self.commands.names();
        let gain = |gains: &[f64], name: &str, k: usize| match gains.len() {
            1 => Ok(gains[0]),
            n if n == names.len() => Ok(gains[k]),
            n => Err(format!(
                "{name} has {n} gains: give one, or one per command joint ({}: {})",
                names.len(),
                names.join(", ")
            )),
        };
        let axes = names
            .iter()
            .enumerate()
            .map(|(k, name)| {
                let index = self
                    .map
                    .index(name)
                    .expect("command joints are the model's");
                let (q_index, v_index) = self.map.slot(index);
                Ok(ServoAxis {
                    q_index,
                    v_index,
                    kp: gain(&settings.servo_kp, "servo_kp", k)?,
                    kd: gain(&settings.servo_kd, "servo_kd", k)?,
                })
            })
            .collect::<Result<_, String>>()?;
        Servo::new(settings.command_interface, axes).map(Some)
    }

    /// A running simulation steps with the engine's forward-dynamics method from its next step
    /// on.
    pub(crate) fn simulate_with_method(&mut self) {
        if let Some(simulation) = &mut self.simulation {
            simulation.sim.config.method = self.method;
        }
    }

    /// What `~/commands` and `~/joint_commands` set: the servos' interface in simulate mode,
    /// else effort.
    pub fn command_interface(&self) -> CommandInterface {
        self.simulation
            .as_ref()
            .and_then(|s| s.servo.as_ref())
            .map_or(CommandInterface::Effort, |s| s.interface())
    }

    /// Targets for the servos: `values[i]` (position or velocity, per the interface) and, for
    /// position servos, `rates[i]` (empty: zero) for command joint `slots[i]`. The caller has
    /// checked the lengths and finiteness.
    pub(crate) fn set_servo_targets(&mut self, slots: &[usize], values: &[f64], rates: &[f64]) {
        let Some(servo) = self.simulation.as_mut().and_then(|s| s.servo.as_mut()) else {
            return;
        };
        let position = servo.interface() == CommandInterface::Position;
        for (i, (&k, &x)) in slots.iter().zip(values).enumerate() {
            let rate = rates.get(i).copied().unwrap_or(0.0);
            if position {
                servo.set_target(k, x, rate);
            } else {
                servo.set_target(k, 0.0, x);
            }
        }
    }

    /// Whether a command may be taken now: with `step_mode: on_command` not while the
    /// simulation is paused or stopped, where it would not step and its sender would wait for
    /// a `joint_states` that does not come.
    pub fn command_can_step(&self) -> Result<(), String> {
        match &self.simulation {
            Some(sim) if sim.lockstep.is_some() && sim.paused => Err(
                "step_mode on_command: the simulation is paused, a command would not step it \
                 (~/pause false resumes it)"
                    .into(),
            ),
            Some(Simulation {
                lockstep: Some(_),
                diverged: Some(why),
                ..
            }) => Err(format!(
                "step_mode on_command: the {why}; a command would not step it (~/reset restarts it)"
            )),
            _ => Ok(()),
        }
    }

    /// After an accepted command with `step_mode: on_command`: advance `steps_per_command`
    /// steps and return the `joint_states` to publish; `None` when free running (or paused or
    /// stopped, where [`command_can_step`](Self::command_can_step) refuses the command).
    pub fn command_step(&mut self, now: Instant) -> Option<Result<(JointState, Time), String>> {
        let sim = self.simulation.as_ref()?;
        let steps = sim.lockstep?;
        if sim.paused || sim.diverged.is_some() {
            return None;
        }
        Some(self.advance(steps, now))
    }

    /// The publish period in simulate mode.
    pub fn simulation_period(&self) -> Option<Duration> {
        self.simulation
            .as_ref()
            .map(|s| Duration::from_secs_f64(1.0 / s.rate))
    }

    /// One tick of the publish timer, due at `due` and run at `now`: advance by
    /// `real_time_factor / publish_rate` seconds (unless paused, diverged or stepping on commands)
    /// and return the `joint_states` to publish with the simulated time. The steps of `sim_dt`
    /// that make up a tick are whole: the fraction left over is owed to the next tick, and a
    /// tick owed less than one step publishes nothing. A tick more than [`MAX_LAG_TICKS`]
    /// periods (and [`MIN_LAG`]) behind `due` does not step: its steps count as missed.
    pub fn simulation_tick(
        &mut self,
        due: Instant,
        now: Instant,
    ) -> Option<Result<(JointState, Time), String>> {
        let sim = self.simulation.as_mut()?;
        if sim.paused || sim.diverged.is_some() || sim.lockstep.is_some() {
            // The timer does not step the simulation: its ticks are neither late nor on time.
            sim.last_tick = None;
            return None;
        }
        let period = Duration::from_secs_f64(1.0 / sim.rate);
        if sim
            .last_tick
            .is_some_and(|last| now.saturating_duration_since(last) > 2 * period)
        {
            sim.late_ticks += 1;
        }
        sim.last_tick = Some(now);
        let owed = sim.owed_steps + (sim.real_time_factor / sim.rate) / sim.sim.config.dt;
        // Within a part in 10⁹ of a whole number of steps, that number: rounding in the
        // quotient must not shift a step to the next tick.
        let whole = (owed + 1e-9 * owed.max(1.0)).floor();
        sim.owed_steps = (owed - whole).max(0.0);
        let steps = whole as usize;
        if now.saturating_duration_since(due) > (MAX_LAG_TICKS * period).max(MIN_LAG) {
            sim.missed_steps += steps as u64;
            return None;
        }
        if steps == 0 {
            return None;
        }
        Some(self.advance(steps, now))
    }

    /// `~/step` while paused: one `sim_dt` step.
    pub fn simulation_step(&mut self, now: Instant) -> Result<(JointState, Time), String> {
        match &self.simulation {
            None => Err("the node is not in simulate mode (parameter mode)".into()),
            Some(s) if !s.paused => {
                Err("the simulation is running: pause it first (~/pause)".into())
            }
            Some(s) if s.diverged.is_some() => Err(format!(
                "the simulation stopped: {}; reset it (~/reset)",
                s.diverged.clone().unwrap_or_default()
            )),
            Some(_) => self.advance(1, now),
        }
    }

    fn advance(&mut self, steps: usize, now: Instant) -> Result<(JointState, Time), String> {
        let sim = self
            .simulation
            .as_mut()
            .expect("advance is only called when simulating");
        let stale = match self.command_time {
            Some(at) => {
                let timeout = sim.command_timeout;
                sim.lockstep.is_none()
                    && timeout > 0.0
                    && now.duration_since(at).as_secs_f64() > timeout
            }
            None => true,
        };
        let feedforward = if stale {
            &sim.zero
        } else {
            self.commands.effort()
        };
        for _ in 0..steps {
            sim.tau.copy_from_slice(feedforward);
            if let (Some(servo), false) = (&sim.servo, stale) {
                servo.add_effort(&sim.state.q, &sim.state.v, &mut sim.tau);
            }
            if let Err(e) = sim.sim.step(&self.model, &mut sim.state, &sim.tau) {
                let message = format!("simulation stopped: {e}");
                sim.diverged = Some(message.clone());
                return Err(message);
            }
        }
        let wall = now.duration_since(sim.measured_since.0).as_secs_f64();
        if wall >= 1.0 {
            sim.measured_rtf = (sim.state.t - sim.measured_since.1) / wall;
            sim.measured_since = (now, sim.state.t);
        }
        let stamp = time_of(sim.state.t);
        let mut position = Vec::new();
        let mut velocity = Vec::new();
        let mut effort = Vec::new();
        self.map
            .gather_all(&sim.state.q, Target::Position, &mut position);
        self.map
            .gather_all(&sim.state.v, Target::Rate, &mut velocity);
        sim.sim.applied_effort(&sim.tau, &mut sim.applied);
        self.map.gather_all(&sim.applied, Target::Rate, &mut effort);
        let js = JointState {
            header: Header {
                stamp: stamp.clone(),
                frame_id: String::new(),
            },
            name: self.map.names().to_vec(),
            position,
            velocity,
            effort,
        };
        Ok((js, stamp))
    }

    /// The floating base in simulate mode, on `~/base_state` as the node reads it in serve mode
    /// (nav_msgs/Odometry): the base link's pose in the `world` frame and its twist in the base
    /// frame, linear then angular; `None` without a floating base.
    pub fn simulated_base_state(&self) -> Option<Odometry> {
        let sim = self.simulation.as_ref()?;
        let (qi, vi) = self.map.base()?;
        let (q, v) = (&sim.state.q[qi..qi + 7], &sim.state.v[vi..vi + 6]);
        let base = self
            .model
            .bodies()
            .iter()
            .find(|b| b.parent.is_none() && b.joint.coords.q_index == qi)?;
        let vector = |x: &[f64]| Vector3 {
            x: x[0],
            y: x[1],
            z: x[2],
        };
        Some(Odometry {
            header: Header {
                stamp: time_of(sim.state.t),
                frame_id: "world".into(),
            },
            child_frame_id: base.name.clone(),
            pose: PoseWithCovariance {
                pose: Pose {
                    position: Point {
                        x: q[0],
                        y: q[1],
                        z: q[2],
                    },
                    orientation: Quaternion {
                        x: q[3],
                        y: q[4],
                        z: q[5],
                        w: q[6],
                    },
                },
                covariance: Covariance::default(),
            },
            twist: TwistWithCovariance {
                twist: Twist {
                    linear: vector(&v[..3]),
                    angular: vector(&v[3..]),
                },
                covariance: Covariance::default(),
            },
        })
    }

    /// Whether the floating base's pose goes on `/tf` (simulate mode, `publish_tf`).
    pub fn publishes_tf(&self) -> bool {
        self.simulation.as_ref().is_some_and(|s| s.publish_tf)
    }

    /// The deepest ground penetration so far (m), in simulate mode with ground contacts.
    pub fn simulated_penetration(&self) -> Option<f64> {
        let sim = self.simulation.as_ref()?;
        (!sim.sim.config.ground.as_ref()?.points.is_empty()).then(|| sim.sim.max_penetration())
    }

    /// `~/pause` (true: pause, false: resume).
    pub fn simulation_pause(&mut self, pause: bool) -> Result<String, String> {
        let sim = self
            .simulation
            .as_mut()
            .ok_or("the node is not in simulate mode (parameter mode)")?;
        sim.paused = pause;
        Ok(format!(
            "{} at t = {:.6} s",
            if pause { "paused" } else { "running" },
            sim.state.t
        ))
    }

    /// `~/reset`: a given state; clears the command (efforts and servo targets back to zero,
    /// servos off until the next command) and any divergence.
    pub fn simulation_reset(&mut self, req: &ResetRequest) -> ResetResponse {
        if self.simulation.is_none() {
            return ResetResponse::refused(
                "the node is not in simulate mode (parameter mode)".into(),
            );
        }
        if let Err(message) = self.read_request_state(req) {
            return ResetResponse::refused(message);
        }
        let sim = self.simulation.as_mut().expect("checked above");
        sim.state.q.copy_from_slice(&self.q);
        sim.state.v.copy_from_slice(&self.v);
        sim.sim.restart_energy_budget();
        sim.diverged = None;
        if let Some(servo) = &mut sim.servo {
            servo.clear_targets();
        }
        self.commands.clear();
        self.command_time = None;
        ResetResponse {
            success: true,
            message: format!("state set at t = {:.6} s", sim.state.t),
        }
    }

    /// The simulated time (s), in simulate mode: the node's clock with `use_sim_time`.
    pub fn simulated_time(&self) -> Option<f64> {
        self.simulation.as_ref().map(|s| s.state.t)
    }

    /// How many publish ticks came more than one period late, in simulate mode.
    pub fn simulation_late_ticks(&self) -> Option<u64> {
        self.simulation.as_ref().map(|s| s.late_ticks)
    }

    /// Steps dropped because their tick came more than [`MAX_LAG_TICKS`] periods after it was
    /// due (simulate mode).
    pub fn simulation_missed_steps(&self) -> Option<u64> {
        self.simulation.as_ref().map(|s| s.missed_steps)
    }

    /// Simulation figures for `/diagnostics`, in simulate mode.
    pub fn simulation_status(&self) -> Option<SimulationStatus> {
        self.simulation.as_ref().map(|s| SimulationStatus {
            t: s.state.t,
            real_time_factor: s.measured_rtf,
            paused: s.paused,
            stopped: s.diverged.clone(),
            clamped: s.sim.clamped(),
            halved: s.sim.halved_steps(),
        })
    }
}

/// What `/diagnostics` says of a simulation.
pub struct SimulationStatus {
    /// Simulated time (s).
    pub t: f64,
    /// Simulated seconds per wall-clock second, measured.
    pub real_time_factor: f64,
    pub paused: bool,
    /// Why the simulation stopped, if it did.
    pub stopped: Option<String>,
    /// Effort evaluations clamped to their URDF limits.
    pub clamped: u64,
    /// Steps implicit Euler halved because Newton's method did not converge on them.
    pub halved: u64,
}

/// Seconds as builtin_interfaces/Time.
pub fn time_of(t: f64) -> Time {
    super::clock::time_from_nanos((t * 1e9).round() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use spatial_dynamics_core::algorithms::ForwardDynamicsMethod;

    /// A `method` set while simulating reaches the simulator: its next step uses it.
    #[test]
    fn a_method_set_while_simulating_is_the_simulators() {
        let settings = Settings {
            simulate: true,
            method: Some(ForwardDynamicsMethod::Aba),
            ..Settings::default()
        };
        let mut engine = Engine::from_settings(&settings, None).unwrap();
        let method = |engine: &Engine| engine.simulation.as_ref().unwrap().sim.config.method;
        assert_eq!(method(&engine), ForwardDynamicsMethod::Aba);
        for m in [
            ForwardDynamicsMethod::Crba,
            ForwardDynamicsMethod::RneaColumns,
        ] {
            engine.set_method(Some(m));
            assert_eq!(method(&engine), m);
        }
    }

    /// Simulate mode's rates that the node's timers could not hold, or that would have one
    /// publish tick run for minutes, are refused naming the parameters, not crashed on.
    #[test]
    fn rates_that_would_stall_the_node_are_refused() {
        use ros2_client::ParameterValue::Double;
        let mut settings = Settings::default();
        for rate in [1e-20, 1e-4, 2e6, 1e12] {
            let e = settings.set("publish_rate", &Double(rate)).unwrap_err();
            assert!(e.contains("'publish_rate'"), "{rate}: {e}");
        }
        for rate in [1e-3, 1e6] {
            settings.set("publish_rate", &Double(rate)).unwrap();
        }
        for (rtf, dt) in [(1e300, 1e-3), (1.0, 1e-300)] {
            let settings = Settings {
                simulate: true,
                real_time_factor: rtf,
                sim_dt: dt,
                ..Settings::default()
            };
            let e = Engine::from_settings(&settings, None)
                .err()
                .expect("refused");
            assert!(
                e.contains("real_time_factor / (publish_rate · sim_dt)"),
                "{e}"
            );
        }
    }

    /// `~/reset` puts the servo targets back to zero: a later command naming only some joints
    /// leaves the others at zero, as after start, not at their targets before the reset.
    #[test]
    fn a_reset_clears_the_servo_targets() {
        let settings = Settings {
            simulate: true,
            command_interface: CommandInterface::Position,
            ..Settings::default()
        };
        let mut engine = Engine::from_settings(&settings, None).unwrap();
        let servo = |engine: &Engine| engine.simulation.as_ref().unwrap().servo.clone().unwrap();
        let fresh = servo(&engine);
        let n = engine.command_names().len();
        let slots: Vec<usize> = (0..n).collect();
        engine.set_servo_targets(&slots, &vec![0.5; n], &vec![0.1; n]);
        assert_ne!(servo(&engine), fresh);
        let reset = engine.simulation_reset(&ResetRequest {
            position: vec![0.0; engine.names().len()],
            ..Default::default()
        });
        assert!(reset.success, "{}", reset.message);
        assert_eq!(servo(&engine), fresh);
    }

    /// A tick owes `real_time_factor / (publish_rate · sim_dt)` steps: a fraction is carried to
    /// the next tick, so simulated time keeps to the factor, and a tick owed less than one step
    /// publishes nothing.
    #[test]
    fn ticks_carry_the_fraction_of_a_step_they_owe() {
        for (rate, dt, steps) in [(400.0, 1e-3, [2, 3, 2, 3]), (2500.0, 1e-3, [0, 0, 1, 0])] {
            let settings = Settings {
                simulate: true,
                publish_rate: rate,
                sim_dt: dt,
                ..Settings::default()
            };
            let mut engine = Engine::from_settings(&settings, None).unwrap();
            let mut taken = 0;
            for expected in steps {
                let now = Instant::now();
                let published = engine.simulation_tick(now, now).is_some();
                assert_eq!(published, expected > 0, "{rate} Hz");
                taken += expected;
                let t = engine.simulated_time().unwrap();
                assert!((t - taken as f64 * dt).abs() < 1e-12, "{rate} Hz: t = {t}");
            }
        }
    }

    /// A tick is dropped as missed only when it is both ten periods and `MIN_LAG` late: at
    /// 100 kHz a tick 5 ms late (the timer's resolution is a millisecond) still steps.
    #[test]
    fn a_tick_within_the_timer_resolution_still_steps() {
        let settings = Settings {
            simulate: true,
            publish_rate: 1e5,
            sim_dt: 1e-5,
            ..Settings::default()
        };
        let mut engine = Engine::from_settings(&settings, None).unwrap();
        let now = Instant::now();
        assert!(engine
            .simulation_tick(now - Duration::from_millis(5), now)
            .is_some());
        assert_eq!(engine.simulation_missed_steps(), Some(0));
        assert!(engine.simulation_tick(now - 2 * MIN_LAG, now).is_none());
        assert_eq!(engine.simulation_missed_steps(), Some(1));
    }
}
