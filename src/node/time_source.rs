//! The node's clock fed from DDS: `use_sim_time` as ros2-client's parameter store holds it (the
//! store keeps that parameter to itself, so it is read before each use), and a `/clock`
//! subscription that exists while simulated time is read from it.
//!
//! The node's time for an input is its clock when the input arrived (DDS receive time), not
//! when the node gets to it, so stamps and stamp checks do not depend on how far behind the
//! node is: the wall clock at arrival, or the latest `/clock` received before the input
//! (`/clock` messages received later wait in `pending` for the next input), or in simulate mode
//! the simulated time reached before it (`ticks`: when, by the wall clock, the simulation
//! reached which time). The rules of the clock itself are in [`super::engine::clock`].

use super::endpoints::{qos, CLOCK_READER_DEPTH};
use super::handlers::NodeState;
use crate::ros::msgs::*;
use ros2_client::dds::rustdds::Topic;
use ros2_client::qos::Durability;
use ros2_client::{Node, ParameterValue, ROSTime, Subscription};
use std::collections::VecDeque;
use std::time::{Duration, SystemTime};

/// Where the node's time comes from, as far as DDS feeds it.
pub struct TimeSource {
    topic: Topic,
    /// The `/clock` subscription and when it was made (RustDDS may hand a new reader samples
    /// its participant received before, for an earlier reader: those are ignored).
    subscription: Option<(Subscription<Clock>, ROSTime)>,
    /// `/clock` messages read but not yet in effect: (received, time).
    pending: VecDeque<(ROSTime, Time)>,
    /// Simulate mode: (wall clock, simulated time in s) of the latest steps, oldest first.
    ticks: VecDeque<(ROSTime, f64)>,
}

impl TimeSource {
    /// A time source reading `/clock` on `topic` when simulated time is on.
    pub fn new(topic: Topic) -> TimeSource {
        TimeSource {
            topic,
            subscription: None,
            pending: VecDeque::with_capacity(CLOCK_READER_DEPTH),
            ticks: VecDeque::with_capacity(CLOCK_READER_DEPTH),
        }
    }

    /// Simulate mode: the simulation has reached `t` (s) at wall time `at`.
    pub fn simulated(&mut self, at: ROSTime, t: Option<f64>) {
        if let Some(t) = t {
            if self.ticks.len() == CLOCK_READER_DEPTH {
                self.ticks.pop_front();
            }
            self.ticks.push_back((at, t));
        }
    }

    /// Forgets the simulation's past steps (the simulation may be new).
    pub fn forget_ticks(&mut self) {
        self.ticks.clear();
    }

    /// Follows `use_sim_time`, applies the `/clock` messages that arrived before `arrived` (all of
    /// them if `None`), and returns the node's time (ns; `None` while simulated time has not
    /// arrived).
    pub fn now(
        &mut self,
        node: &mut Node,
        state: &mut NodeState,
        arrived: Option<ROSTime>,
    ) -> Option<i64> {
        let wanted = matches!(
            node.get_parameter("use_sim_time"),
            Some(ParameterValue::Boolean(true))
        );
        state.follow_use_sim_time(wanted);
        let simulating = state.engine.simulated_time().is_some();
        if !state.clock.reads_clock(simulating) {
            self.subscription = None;
            self.pending.clear();
        } else if self.subscription.is_none() {
            // rclcpp's ClockQoS is best effort, keep last 1; the reader keeps more (a local
            // choice, no effect on matching) so that none is lost between two inputs.
            match node.create_subscription::<Clock>(
                &self.topic,
                Some(qos(false, Durability::Volatile, CLOCK_READER_DEPTH)),
            ) {
                Ok(sub) => self.subscription = Some((sub, node.time_now_not_simulated())),
                Err(e) => state
                    .health
                    .dropped(&state.names.clock, &format!("cannot subscribe: {e:?}")),
            }
        }
        if let Some((sub, since)) = &self.subscription {
            loop {
                match sub.take() {
                    Ok(Some((message, info))) => {
                        let received = info.received_timestamp().unwrap_or(ROSTime::ZERO);
                        if received >= *since || received == ROSTime::ZERO {
                            state.health.received(&state.names.clock);
                            self.pending.push_back((received, message.clock));
                        }
                    }
                    Ok(None) => break,
                    Err(e) => {
                        state
                            .health
                            .dropped(&state.names.clock, &format!("unreadable message: {e:?}"));
                        break;
                    }
                }
            }
        }
        while let Some((received, _)) = self.pending.front() {
            if arrived.is_some_and(|a| *received > a) {
                break;
            }
            let (_, t) = self.pending.pop_front().expect("front exists");
            state.clock_received(&t);
        }
        // Simulate mode: the simulated time reached before the input arrived.
        let simulated = state.engine.simulated_time().map(|now| {
            arrived
                .and_then(|a| self.ticks.iter().rev().find(|(at, _)| *at <= a))
                .map_or(now, |(_, t)| *t)
        });
        // Wall clock: the input's DDS receive time.
        let wall = arrived
            .and_then(|a| u64::try_from(a.to_nanos()).ok())
            .map_or_else(SystemTime::now, |n| {
                SystemTime::UNIX_EPOCH + Duration::from_nanos(n)
            });
        state.clock.now(wall, simulated)
    }
}
