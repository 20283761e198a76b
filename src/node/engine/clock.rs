//! The node's clock, the stamps it gives its outputs, and its policy for input stamps. Free of
//! DDS: the node feeds it `/clock` messages and asks it for the time.
//!
//! **Which clock.** Without `use_sim_time` the node's clock is the wall clock (system time, ns
//! since the Unix epoch). With `use_sim_time` it is ROS simulated time: in serve mode the latest
//! `/clock` message received (it may jump backwards, e.g. when a bag loops; the latest wins); in
//! simulate mode the node's own simulated time (`/clock` from others is not read: the simulating
//! node is the clock, and publishes it with `publish_clock`).
//!
//! **Output stamps.** Without `use_sim_time` an output carries its input's header stamp
//! (unchanged behaviour). With `use_sim_time` every output is stamped with the node's clock as it
//! stood when the input arrived: the latest `/clock` received before the input (by DDS receive
//! time), or in simulate mode the simulated time reached before it, so a node running behind
//! still stamps an answer with its input's time. Before the first `/clock` arrives (serve mode) the time is unknown: topic
//! inputs are dropped, counted as `waiting for /clock`, rather than answered with stamp 0;
//! `/diagnostics` still goes out, stamped 0 as rclcpp's clock reads then.
//!
//! **Input stamps** (`joint_states`; the request types of the services carry no stamp), against
//! the node's clock when the message arrived (so a node running behind does not call a message
//! stale for its own delay). With
//! `max_stamp_age = A > 0` a message stamped more than `A` seconds before the node's clock is
//! dropped as `stale stamp`; with `future_stamp_tolerance = F > 0` one stamped more than `F`
//! seconds after it is dropped as `stamp from the future`. Each 0 switches its check off (the
//! default). A zero stamp (header not filled in) is therefore stale whenever the age check is on.

use crate::node::params::Settings;
use crate::ros::msgs::Time;
use std::time::{SystemTime, UNIX_EPOCH};

const NS: i64 = 1_000_000_000;

/// The node's time source and stamp policy.
#[derive(Clone, Debug)]
pub struct NodeClock {
    use_sim_time: bool,
    /// Latest `/clock` time (ns), none before the first one (or since `use_sim_time` was set).
    latest_clock: Option<i64>,
    /// `max_stamp_age` and `future_stamp_tolerance`, in ns (0: that check is off).
    max_age: i64,
    max_lead: i64,
}

/// Where the node's time came from, for `/diagnostics`.
pub fn source_name(use_sim_time: bool, simulating: bool) -> &'static str {
    match (use_sim_time, simulating) {
        (false, _) => "wall clock",
        (true, false) => "/clock (use_sim_time)",
        (true, true) => "own simulated time (use_sim_time, simulate mode)",
    }
}

impl NodeClock {
    pub fn new(settings: &Settings) -> NodeClock {
        let mut clock = NodeClock {
            use_sim_time: settings.use_sim_time,
            latest_clock: None,
            max_age: 0,
            max_lead: 0,
        };
        clock.configure(settings);
        clock
    }

    /// Takes the stamp policy from the settings (`use_sim_time` goes through
    /// [`NodeClock::set_use_sim_time`]).
    pub fn configure(&mut self, settings: &Settings) {
        self.max_age = seconds_to_nanos(settings.max_stamp_age);
        self.max_lead = seconds_to_nanos(settings.future_stamp_tolerance);
    }

    pub fn use_sim_time(&self) -> bool {
        self.use_sim_time
    }

    /// Switches simulated time on or off; on a change, forgets the last `/clock`.
    pub fn set_use_sim_time(&mut self, on: bool) {
        if on != self.use_sim_time {
            self.use_sim_time = on;
            self.latest_clock = None;
        }
    }

    /// Whether the node must read `/clock` (simulated time, not simulating itself).
    pub fn reads_clock(&self, simulating: bool) -> bool {
        self.use_sim_time && !simulating
    }

    /// A `/clock` message: its time becomes the node's. Returns a note when time went backwards.
    pub fn clock_received(&mut self, t: &Time) -> Option<String> {
        let t = nanos(t);
        let before = self.latest_clock.replace(t);
        before.filter(|&b| t < b).map(|b| {
            format!(
                "/clock went back from {} s to {} s (a bag looped or restarted?)",
                seconds(b),
                seconds(t)
            )
        })
    }

    /// The node's time (ns): the wall clock, the latest `/clock`, or `simulated` (seconds) in
    /// simulate mode; `None` while simulated time is on and no `/clock` has arrived.
    pub fn now(&self, wall: SystemTime, simulated: Option<f64>) -> Option<i64> {
        match (self.use_sim_time, simulated) {
            (false, _) => Some(
                wall.duration_since(UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos().min(i64::MAX as u128) as i64),
            ),
            (true, Some(t)) => Some(seconds_to_nanos(t)),
            (true, None) => self.latest_clock,
        }
    }

    /// The stamp for an output computed now from an input stamped `input`: the input's stamp,
    /// or with simulated time the node's time (an error while it is unknown).
    pub fn output_stamp(&self, input: &Time, now: Option<i64>) -> Result<Time, String> {
        if !self.use_sim_time {
            return Ok(input.clone());
        }
        now.map(time_from_nanos).ok_or_else(|| {
            "waiting for /clock (use_sim_time is true and no /clock message has arrived yet)".into()
        })
    }

    /// Checks an input's stamp against the policy; on success, the stamp for its outputs.
    pub fn admit(&self, stamp: &Time, now: Option<i64>) -> Result<Time, String> {
        let out = self.output_stamp(stamp, now)?;
        let Some(now) = now else { return Ok(out) };
        let (t, clock) = (nanos(stamp), self.clock_word());
        if self.max_age > 0 && now - t > self.max_age {
            return Err(format!(
                "stale stamp ({} s is {} s behind the node's {clock} time {} s; max_stamp_age {} s)",
                seconds(t),
                seconds(now - t),
                seconds(now),
                seconds(self.max_age)
            ));
        }
        if self.max_lead > 0 && t - now > self.max_lead {
            return Err(format!(
                "stamp from the future ({} s is {} s ahead of the node's {clock} time {} s; future_stamp_tolerance {} s)",
                seconds(t),
                seconds(t - now),
                seconds(now),
                seconds(self.max_lead)
            ));
        }
        Ok(out)
    }

    /// The node's time as a stamp for messages it makes itself (0 while unknown, like rclcpp).
    pub fn stamp(now: Option<i64>) -> Time {
        time_from_nanos(now.unwrap_or(0))
    }

    fn clock_word(&self) -> &'static str {
        if self.use_sim_time {
            "simulated"
        } else {
            "wall-clock"
        }
    }
}

/// A stamp in ns (`sec · 10⁹ + nanosec`).
pub fn nanos(t: &Time) -> i64 {
    t.sec as i64 * NS + t.nanosec as i64
}

/// ns as builtin_interfaces/Time (`nanosec` in `[0, 10⁹)`).
pub fn time_from_nanos(n: i64) -> Time {
    Time {
        sec: n.div_euclid(NS) as i32,
        nanosec: n.rem_euclid(NS) as u32,
    }
}

/// Seconds (finite, ≥ 0 as the parameters are validated) as ns.
fn seconds_to_nanos(s: f64) -> i64 {
    (s * 1e9).round() as i64
}

/// ns printed as seconds with all nine decimals (`-` for negative).
fn seconds(n: i64) -> String {
    let sign = if n < 0 { "-" } else { "" };
    let a = n.unsigned_abs();
    format!("{sign}{}.{:09}", a / NS as u64, a % NS as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn t(sec: i32, nanosec: u32) -> Time {
        Time { sec, nanosec }
    }

    fn clock(use_sim_time: bool, age: f64, lead: f64) -> NodeClock {
        NodeClock::new(&Settings {
            use_sim_time,
            max_stamp_age: age,
            future_stamp_tolerance: lead,
            ..Settings::default()
        })
    }

    #[test]
    fn wall_clock_keeps_input_stamps() {
        let c = clock(false, 0.0, 0.0);
        let wall = UNIX_EPOCH + Duration::new(1_700_000_000, 250);
        let now = c.now(wall, None);
        assert_eq!(now, Some(1_700_000_000 * NS + 250));
        // Any stamp passes with the checks off, and is kept.
        assert_eq!(c.admit(&t(3, 7), now), Ok(t(3, 7)));
        assert_eq!(c.admit(&t(2_000_000_000, 0), now), Ok(t(2_000_000_000, 0)));
    }

    #[test]
    fn sim_time_stamps_with_the_latest_clock_and_waits_for_the_first() {
        let mut c = clock(true, 0.0, 0.0);
        let wall = SystemTime::now();
        let err = c.admit(&t(5, 0), c.now(wall, None)).unwrap_err();
        assert!(err.starts_with("waiting for /clock"), "{err}");
        assert_eq!(NodeClock::stamp(c.now(wall, None)), t(0, 0));
        assert_eq!(c.clock_received(&t(10, 500)), None);
        assert_eq!(c.admit(&t(5, 0), c.now(wall, None)), Ok(t(10, 500)));
        // Backwards (a looping bag): the latest wins, with a note.
        let note = c.clock_received(&t(1, 0)).unwrap();
        assert!(note.contains("10.000000500 s to 1.000000000 s"), "{note}");
        assert_eq!(c.admit(&t(5, 0), c.now(wall, None)), Ok(t(1, 0)));
        // Turning it off and on forgets the last /clock.
        c.set_use_sim_time(false);
        c.set_use_sim_time(true);
        assert_eq!(c.now(wall, None), None);
        // Simulate mode: the node's own time, no /clock needed.
        assert!(!c.reads_clock(true) && c.reads_clock(false));
        assert_eq!(c.now(wall, Some(2.5)), Some(2_500_000_000));
    }

    #[test]
    fn stale_and_future_stamps_are_refused_naming_the_stamp() {
        let mut c = clock(true, 0.5, 0.01);
        c.clock_received(&t(100, 0));
        let now = c.now(SystemTime::now(), None);
        // Exactly at the limits passes; one nanosecond beyond does not.
        assert_eq!(c.admit(&t(99, 500_000_000), now), Ok(t(100, 0)));
        assert_eq!(c.admit(&t(100, 10_000_000), now), Ok(t(100, 0)));
        let stale = c.admit(&t(99, 499_999_999), now).unwrap_err();
        assert_eq!(
            stale,
            "stale stamp (99.499999999 s is 0.500000001 s behind the node's simulated time \
             100.000000000 s; max_stamp_age 0.500000000 s)"
        );
        let future = c.admit(&t(100, 10_000_001), now).unwrap_err();
        assert!(
            future.starts_with("stamp from the future (100.010000001 s is 0.010000001 s ahead"),
            "{future}"
        );
        // An unfilled header is stale when the age check is on.
        assert!(c.admit(&t(0, 0), now).unwrap_err().starts_with("stale"));
        // Off: anything goes.
        c.configure(&Settings::default());
        assert!(c.admit(&t(0, 0), now).is_ok() && c.admit(&t(1_000_000, 0), now).is_ok());
    }

    #[test]
    fn nanosecond_conversions_round_trip() {
        for n in [
            0,
            1,
            NS - 1,
            NS,
            1_700_000_000 * NS + 123_456_789,
            -1,
            -NS - 1,
        ] {
            assert_eq!(nanos(&time_from_nanos(n)), n);
            assert!(time_from_nanos(n).nanosec < NS as u32);
        }
        assert_eq!(seconds(-1), "-0.000000001");
    }
}
