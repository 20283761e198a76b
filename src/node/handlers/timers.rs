//! The node's timers: the simulation's publish timer (simulate mode) and `/diagnostics` (1 Hz).

use super::{checked, NodeState, Outputs};
use crate::node::engine::clock::{self, NodeClock};
use crate::node::engine::{simulation, Engine};
use crate::node::logging::log;
use crate::ros::msgs::*;
use std::time::Instant;

/// The publish timer of simulate mode, one tick per `1 / publish_rate` s (none in serve mode),
/// the first one period from now. Ticks the process was too busy or too stalled to run come at
/// once when it can, so the simulation keeps to wall-clock time; those more than
/// [`MAX_LAG_TICKS`](crate::node::engine::simulation::MAX_LAG_TICKS) periods late are dropped
/// ([`Engine::simulation_tick`]).
pub fn simulation_timer(engine: &Engine) -> Option<tokio::time::Interval> {
    engine.simulation_period().map(|period| {
        let mut timer = tokio::time::interval_at(tokio::time::Instant::now() + period, period);
        timer.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Burst);
        timer
    })
}

/// The base pose of `~/base_state` as one world → base link transform for `/tf` (same stamp,
/// same frames).
fn tf_of(odometry: &Odometry) -> TFMessage {
    let pose = &odometry.pose.pose;
    TFMessage {
        transforms: vec![TransformStamped {
            header: odometry.header.clone(),
            child_frame_id: odometry.child_frame_id.clone(),
            transform: TransformMsg {
                translation: Vector3 {
                    x: pose.position.x,
                    y: pose.position.y,
                    z: pose.position.z,
                },
                rotation: pose.orientation.clone(),
            },
        }],
    }
}

impl NodeState {
    /// A tick of the simulation's publish timer due at `due`, run at wall time `now`: the
    /// simulation advances by `real_time_factor / publish_rate` s (unless paused, stopped or
    /// the tick is too late) and its state goes out.
    pub fn simulation_tick(&mut self, due: Instant, now: Instant) -> Outputs {
        let missed = self.engine.simulation_missed_steps();
        let tick = self.engine.simulation_tick(due, now);
        if self.engine.simulation_missed_steps() > missed {
            let reason = format!(
                "the simulation is behind real time: a publish tick ran more than {} periods \
                 (and {} ms) late, its steps are counted as missed steps",
                simulation::MAX_LAG_TICKS,
                simulation::MIN_LAG.as_millis()
            );
            self.health.dropped(&self.names.joint_states, &reason);
        }
        self.simulation_outputs(tick)
    }

    /// What a simulation step gives to publish: `joint_states`, a floating base's
    /// `~/base_state` (and its pose on `/tf` with `publish_tf`), and `/clock` when `publish_clock` is set; or, when the simulation
    /// stopped (diverged), nothing, and the reason logged as an error.
    pub(super) fn simulation_outputs(
        &mut self,
        step: Option<Result<(JointState, Time), String>>,
    ) -> Outputs {
        let mut out = Outputs::default();
        match step {
            None => {}
            Some(Ok((js, stamp))) => {
                let publish_clock = self
                    .settings
                    .lock()
                    .map(|s| s.publish_clock)
                    .unwrap_or(false);
                if publish_clock {
                    out.clock = Some(Clock { clock: stamp });
                }
                out.joint_states = checked(&mut self.health, js, &self.names.joint_states);
                if let Some(odometry) = self.engine.simulated_base_state() {
                    out.base_state = checked(&mut self.health, odometry, &self.names.base_state);
                }
                if self.engine.publishes_tf() {
                    out.tf = out.base_state.as_ref().map(tf_of);
                }
            }
            Some(Err(why)) => log!(self.logger, Error, "{why}"),
        }
        out
    }

    /// `/diagnostics` at the node's time `now` (ns; stamped 0 while unknown): the counters
    /// ([`crate::node::health::Health::report`]), the clock in use and its time, and in simulate mode the
    /// simulation's time, real-time factor, late publish ticks (more than two periods after the
    /// tick before), missed steps (ticks dropped as too late) and state (an error status once it
    /// diverged).
    pub fn diagnostics(&mut self, now: Option<i64>) -> Outputs {
        let simulating = self.engine.simulated_time().is_some();
        let mut status = self
            .health
            .report(&self.names.status, self.engine.model.name(), true);
        let mut value = |key: &str, value: String| {
            status.values.push(KeyValue {
                key: key.into(),
                value,
            })
        };
        value(
            "clock",
            clock::source_name(self.clock.use_sim_time(), simulating).into(),
        );
        value(
            "clock time (s)",
            now.map_or_else(|| "none yet".into(), |n| format!("{:.9}", n as f64 * 1e-9)),
        );
        let mut diverged = None;
        if let Some(sim) = self.engine.simulation_status() {
            value("simulated time (s)", format!("{:.6}", sim.t));
            value("real-time factor", format!("{:.3}", sim.real_time_factor));
            value("paused", sim.paused.to_string());
            value("efforts clamped", sim.clamped.to_string());
            value("steps halved (implicit Euler)", sim.halved.to_string());
            if let Some(late) = self.engine.simulation_late_ticks() {
                value("late publish ticks", late.to_string());
            }
            if let Some(missed) = self.engine.simulation_missed_steps() {
                value("missed steps", missed.to_string());
            }
            if let Some(depth) = self.engine.simulated_penetration() {
                value("deepest ground penetration (m)", format!("{depth:.6}"));
            }
            diverged = sim.stopped;
        }
        if let Some(why) = diverged {
            status.level = 2;
            status.message = why;
        }
        Outputs {
            diagnostics: Some(DiagnosticArray {
                header: Header {
                    stamp: NodeClock::stamp(now),
                    frame_id: String::new(),
                },
                status: vec![status],
            }),
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::*;
    use crate::node::params::Settings;
    use spatial_dynamics_core::model::examples::PARTICLE_URDF;

    /// The particle in simulate mode: 100 ticks a second of 1 ms steps in real time.
    fn falling(publish_clock: bool) -> NodeState {
        serving(Settings {
            robot_description: PARTICLE_URDF.into(),
            simulate: true,
            sim_dt: 1e-3,
            publish_rate: 100.0,
            real_time_factor: 1.0,
            publish_clock,
            ..Settings::default()
        })
    }

    /// The particle's fall after n semi-implicit Euler steps of dt from rest:
    /// v_n = −g n dt, z_n = Σ v_k dt = −g dt² n (n + 1) / 2.
    fn fall(n: f64, dt: f64) -> (f64, f64) {
        (-G * dt * dt * n * (n + 1.0) / 2.0, -G * n * dt)
    }

    #[test]
    fn simulate_mode_ticks_advance_the_state_and_publish_it() {
        let mut state = falling(true);
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .unwrap();
        let _in_runtime = runtime.enter();
        let period = simulation_timer(&state.engine).expect("a timer").period();
        assert_eq!(period, std::time::Duration::from_millis(10));
        for tick in 1..=2 {
            let out = state.simulation_tick_now();
            let js = out.joint_states.expect("joint_states");
            let (z, v) = fall(10.0 * tick as f64, 1e-3);
            assert_close(js.position[1], z);
            assert_close(js.velocity[1], v);
            assert_close(js.position[0], 0.0);
            let t = Time {
                sec: 0,
                nanosec: 10_000_000 * tick,
            };
            assert_eq!(js.header.stamp, t);
            assert_eq!(out.clock.expect("publish_clock is on").clock, t);
            assert!(out.base_state.is_none(), "a fixed base");
        }
        assert_close(state.engine.simulated_time().unwrap(), 0.02);
        // Paused: no step, nothing published.
        assert!(state.pause(&SetBoolRequest { data: true }).success);
        let out = state.simulation_tick_now();
        assert!(out.joint_states.is_none() && out.clock.is_none());
        assert_close(state.engine.simulated_time().unwrap(), 0.02);
        // Serve mode has no timer.
        assert!(simulation_timer(&serving(pendulum()).engine).is_none());
    }

    #[test]
    fn a_floating_base_goes_on_tf_with_its_base_state_unless_publish_tf_is_off() {
        let box_settings = |publish_tf| {
            Settings {
            robot_description: r#"<robot name="box"><link name="box"><inertial><mass value="2"/>
                <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"#
                .into(),
            floating_base: true,
            simulate: true,
            publish_tf,
            ..Settings::default()
        }
        };
        let mut state = serving(box_settings(true));
        let out = state.simulation_tick_now();
        let odometry = out.base_state.expect("a floating base");
        let tf = out.tf.expect("publish_tf is on");
        assert_eq!(tf.transforms.len(), 1);
        let t = &tf.transforms[0];
        assert_eq!(t.header, odometry.header);
        assert_eq!(t.header.frame_id, "world");
        assert_eq!(t.child_frame_id, "box");
        // Free fall over 10 steps of 1 ms: z = −g dt² n (n + 1) / 2.
        assert_close(t.transform.translation.z, fall(10.0, 1e-3).0);
        assert_eq!(t.transform.rotation, odometry.pose.pose.orientation);
        let mut off = serving(box_settings(false));
        let out = off.simulation_tick_now();
        assert!(out.base_state.is_some() && out.tf.is_none());
        // A fixed base has no transform to publish.
        assert!(falling(false).simulation_tick_now().tf.is_none());
    }

    #[test]
    fn without_publish_clock_no_clock_goes_out() {
        let mut state = falling(false);
        let out = state.simulation_tick_now();
        assert!(out.joint_states.is_some() && out.clock.is_none());
    }

    #[test]
    fn diagnostics_report_counters_clock_and_simulation() {
        let mut state = falling(false);
        state.simulation_tick_now();
        state.commands(Ok(Float64MultiArray::default()));
        state.effort_command(Err("unreadable message: x".into()));
        let now = 1_500_000_000;
        let out = state.diagnostics(Some(now));
        let array = out.diagnostics.expect("diagnostics");
        assert_eq!(
            array.header.stamp,
            Time {
                sec: 1,
                nanosec: 500_000_000
            }
        );
        let status = &array.status[0];
        assert_eq!(status.name, "spatial_dynamics: dynamics");
        assert_eq!(status.hardware_id, "particle");
        assert_eq!(status.level, 1, "{}", status.message);
        let value = |key: &str| {
            let found = status.values.iter().find(|v| v.key == key);
            found
                .map(|v| v.value.as_str())
                .unwrap_or_else(|| panic!("no {key}"))
        };
        assert_eq!(value("clock"), "wall clock");
        assert_eq!(value("clock time (s)"), "1.500000000");
        assert_eq!(value("simulated time (s)"), "0.010000");
        assert_eq!(value("paused"), "false");
        assert_eq!(
            value("/spatial_dynamics/effort_command dropped: unreadable message: x"),
            "1"
        );
        assert_eq!(value("/spatial_dynamics/commands received"), "1");
        // Unknown time: stamped 0.
        let array = state.diagnostics(None).diagnostics.unwrap();
        assert_eq!(array.header.stamp, Time::default());
        let status = &array.status[0];
        let clock_time = status
            .values
            .iter()
            .find(|v| v.key == "clock time (s)")
            .unwrap();
        assert_eq!(clock_time.value, "none yet");
        // Serve mode: no simulation figures.
        let mut serve = serving(pendulum());
        let status = &serve.diagnostics(Some(0)).diagnostics.unwrap().status[0];
        assert_eq!(status.level, 0);
        assert!(!status.values.iter().any(|v| v.key == "simulated time (s)"));
    }

    /// The value of the diagnostics entry `key` (the node's clock at 0).
    fn diagnostic(state: &mut NodeState, key: &str) -> String {
        let status = &state.diagnostics(Some(0)).diagnostics.unwrap().status[0];
        let found = status.values.iter().find(|v| v.key == key);
        found.unwrap_or_else(|| panic!("no {key}")).value.clone()
    }

    /// A tick more than two periods after the one before is late; jitter within that is not.
    #[test]
    fn diagnostics_count_late_publish_ticks() {
        let mut state = falling(false);
        let period = state.engine.simulation_period().expect("simulate mode");
        let late = |state: &mut NodeState| diagnostic(state, "late publish ticks");
        let t0 = Instant::now();
        state.simulation_tick(t0, t0);
        assert_eq!(late(&mut state), "0");
        let t1 = t0 + period * 19 / 10;
        state.simulation_tick(t1, t1);
        assert_eq!(late(&mut state), "0", "1.9 periods: on time");
        let t2 = t1 + period * 21 / 10;
        state.simulation_tick(t2, t2);
        assert_eq!(late(&mut state), "1", "2.1 periods: late");
        // Paused, the timer steps nothing: a gap while paused, or up to the first tick after
        // resuming, is no late tick.
        state.engine.simulation_pause(true).unwrap();
        let t3 = t2 + period * 5;
        state.simulation_tick(t3, t3);
        let t4 = t3 + period * 5;
        state.simulation_tick(t4, t4);
        state.engine.simulation_pause(false).unwrap();
        let t5 = t4 + period * 5;
        state.simulation_tick(t5, t5);
        assert_eq!(
            late(&mut state),
            "1",
            "ticks while paused and the first after"
        );
    }

    /// A tick run more than `MAX_LAG_TICKS` periods after it was due does not step and counts
    /// its steps as missed; one within that steps as though on time.
    /// (`falling`: ticks of 10 ms, steps of 1 ms.)
    #[test]
    fn ticks_too_far_behind_are_dropped_and_counted_as_missed_steps() {
        use crate::node::engine::simulation::MAX_LAG_TICKS;
        let mut state = falling(false);
        let period = state.engine.simulation_period().expect("simulate mode");
        let missed = |state: &mut NodeState| diagnostic(state, "missed steps");
        let due = Instant::now();
        let within = state.simulation_tick(due, due + period * (MAX_LAG_TICKS - 1));
        assert!(
            within.joint_states.is_some(),
            "late within the bound: a step"
        );
        assert_eq!(missed(&mut state), "0");
        let t = state.engine.simulated_time().unwrap();
        let beyond = state.simulation_tick(due, due + period * (MAX_LAG_TICKS + 1));
        assert!(beyond.joint_states.is_none(), "beyond the bound: no step");
        assert_eq!(state.engine.simulated_time().unwrap(), t);
        let steps_per_tick = (period.as_secs_f64() / 1e-3).round();
        assert_eq!(missed(&mut state), steps_per_tick.to_string());
    }
}
