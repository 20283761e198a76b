//! The node's timers: the simulation's publish timer (simulate mode) and `/diagnostics` (1 Hz).

use super::{checked, NodeState, Outputs};
use crate::node::engine::clock::{self, NodeClock};
use crate::node::engine::Engine;
use crate::node::logging::log;
use crate::ros::msgs::*;
use std::time::Instant;

/// The publish timer of simulate mode, one tick per `1 / publish_rate` s (none in serve mode).
/// A late tick delays the ones after it rather than bunching them.
pub fn simulation_timer(engine: &Engine) -> Option<tokio::time::Interval> {
    engine.simulation_period().map(|period| {
        let mut timer = tokio::time::interval(period);
        timer.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        timer
    })
}

impl NodeState {
    /// A tick of the simulation's publish timer at wall time `at`: the simulation advances by
    /// `real_time_factor / publish_rate` s (unless paused or stopped) and its state goes out.
    pub fn simulation_tick(&mut self, at: Instant) -> Outputs {
        let tick = self.engine.simulation_tick(at);
        self.simulation_outputs(tick)
    }

    /// What a simulation step gives to publish: `joint_states`, a floating base's
    /// `~/base_state`, and `/clock` when `publish_clock` is set; or, when the simulation
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
            }
            Some(Err(why)) => log!(self.logger, Error, "{why}"),
        }
        out
    }

    /// `/diagnostics` at the node's time `now` (ns; stamped 0 while unknown): the counters
    /// ([`crate::node::health::Health::report`]), the clock in use and its time, and in simulate mode the
    /// simulation's time, real-time factor and state (an error status once it diverged).
    pub fn diagnostics(&mut self, now: Option<i64>) -> Outputs {
        let simulating = self.engine.simulated_time().is_some();
        let mut status = self
            .health
            .report(&self.names.status, &self.engine.model.name, true);
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
        if let Some((t, rtf, paused, why, clamped)) = self.engine.simulation_status() {
            value("simulated time (s)", format!("{t:.6}"));
            value("real-time factor", format!("{rtf:.3}"));
            value("paused", paused.to_string());
            value("efforts clamped", clamped.to_string());
            if let Some(depth) = self.engine.simulated_penetration() {
                value("deepest ground penetration (m)", format!("{depth:.6}"));
            }
            diverged = why;
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
