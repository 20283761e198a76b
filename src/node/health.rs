//! What the node counts and reports on `/diagnostics`: inputs received and dropped (by topic and
//! reason), outputs published, compute time per message; and warnings limited to one a second per
//! topic, with the number suppressed.

use super::logging::{log, Logger};
use crate::ros::msgs::{DiagnosticStatus, KeyValue};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// Counters since start, and since the last report for rates.
#[derive(Debug)]
pub struct Health {
    received: BTreeMap<String, u64>,
    dropped: BTreeMap<(String, String), u64>,
    published: BTreeMap<String, u64>,
    received_at_report: BTreeMap<String, u64>,
    /// [`Health::total_dropped`] at the last report.
    dropped_at_report: u64,
    compute_total: Duration,
    compute_max: Duration,
    computed: u64,
    last_report: Instant,
    last_warning: BTreeMap<String, (Instant, u64)>,
    logger: Logger,
}

impl Health {
    /// Counters at zero; warnings go to `logger`.
    pub fn new(logger: Logger) -> Self {
        Health {
            received: BTreeMap::new(),
            dropped: BTreeMap::new(),
            published: BTreeMap::new(),
            received_at_report: BTreeMap::new(),
            dropped_at_report: 0,
            compute_total: Duration::ZERO,
            compute_max: Duration::ZERO,
            computed: 0,
            last_report: Instant::now(),
            last_warning: BTreeMap::new(),
            logger,
        }
    }
}

/// Keeps only the part of a reason before any detail, with every number written `N`, so
/// counters group by kind of problem (`unknown joint 'x' in name` and `unknown joint 'y' in
/// name` count together, as do `position has 3 values for 7 names` and `… 9 values …`) and
/// no input can add counters without end.
fn reason_kind(reason: &str) -> String {
    let cut = reason
        .find(['\'', '"', '(', '[', '{'])
        .unwrap_or(reason.len());
    let mut kind = String::new();
    let mut in_number = false;
    for c in reason[..cut].trim().chars() {
        if !c.is_ascii_digit() {
            kind.push(c);
        } else if !in_number {
            kind.push('N');
        }
        in_number = c.is_ascii_digit();
    }
    kind
}

impl Health {
    /// An input arrived on `topic`.
    pub fn received(&mut self, topic: &str) {
        *self.received.entry(topic.to_string()).or_default() += 1;
    }

    /// An input on `topic` was dropped for `reason`: counted, and warned about at most once a
    /// second per topic.
    pub fn dropped(&mut self, topic: &str, reason: &str) {
        *self
            .dropped
            .entry((topic.to_string(), reason_kind(reason)))
            .or_default() += 1;
        let now = Instant::now();
        let entry = self
            .last_warning
            .entry(topic.to_string())
            .or_insert((now - Duration::from_secs(2), 0));
        if now.duration_since(entry.0) >= Duration::from_secs(1) {
            let suppressed = std::mem::take(&mut entry.1);
            entry.0 = now;
            let more = if suppressed > 0 {
                format!(" ({suppressed} more dropped since the last warning)")
            } else {
                String::new()
            };
            log!(
                self.logger,
                Warn,
                "dropped a message on {topic}: {reason}{more}"
            );
        } else {
            entry.1 += 1;
        }
    }

    /// An output was published on `topic`.
    pub fn published(&mut self, topic: &str) {
        *self.published.entry(topic.to_string()).or_default() += 1;
    }

    /// One message's computation took `elapsed`.
    pub fn computed(&mut self, elapsed: Duration) {
        self.compute_total += elapsed;
        self.compute_max = self.compute_max.max(elapsed);
        self.computed += 1;
    }

    /// Total inputs dropped.
    pub fn total_dropped(&self) -> u64 {
        self.dropped.values().sum()
    }

    /// How many inputs on `topic` were received (for tests).
    #[cfg(test)]
    pub fn received_on(&self, topic: &str) -> u64 {
        self.received.get(topic).copied().unwrap_or(0)
    }

    /// How many inputs on `topic` were dropped for reasons of the kind of `reason` (for tests).
    #[cfg(test)]
    pub fn dropped_on(&self, topic: &str, reason: &str) -> u64 {
        let key = (topic.to_string(), reason_kind(reason));
        self.dropped.get(&key).copied().unwrap_or(0)
    }

    /// The status for `/diagnostics` (its hardware id: the robot model's name), and a reset of
    /// the per-period figures.
    pub fn report(&mut self, name: &str, model: &str, model_ok: bool) -> DiagnosticStatus {
        let now = Instant::now();
        let period = now.duration_since(self.last_report).as_secs_f64().max(1e-9);
        let mut values = vec![KeyValue {
            key: "model".into(),
            value: model.into(),
        }];
        for (topic, &count) in &self.received {
            let before = self.received_at_report.get(topic).copied().unwrap_or(0);
            values.push(KeyValue {
                key: format!("{topic} received"),
                value: count.to_string(),
            });
            values.push(KeyValue {
                key: format!("{topic} rate (Hz)"),
                value: format!("{:.1}", (count - before) as f64 / period),
            });
        }
        for ((topic, reason), count) in &self.dropped {
            values.push(KeyValue {
                key: format!("{topic} dropped: {reason}"),
                value: count.to_string(),
            });
        }
        for (topic, count) in &self.published {
            values.push(KeyValue {
                key: format!("{topic} published"),
                value: count.to_string(),
            });
        }
        if self.computed > 0 {
            let mean = self.compute_total.as_secs_f64() / self.computed as f64;
            values.push(KeyValue {
                key: "compute mean (us)".into(),
                value: format!("{:.2}", mean * 1e6),
            });
            values.push(KeyValue {
                key: "compute max (us)".into(),
                value: format!("{:.2}", self.compute_max.as_secs_f64() * 1e6),
            });
        }
        self.received_at_report = self.received.clone();
        self.compute_total = Duration::ZERO;
        self.compute_max = Duration::ZERO;
        self.computed = 0;
        self.last_report = now;
        let dropped = self.total_dropped();
        let recent = dropped - std::mem::replace(&mut self.dropped_at_report, dropped);
        // WARN while inputs are being dropped, back to OK once a report period passes without.
        let (level, message) = match (model_ok, recent, dropped) {
            (false, _, _) => (2, "no usable model".to_string()),
            (true, 0, 0) => (0, "ok".to_string()),
            (true, 0, n) => (
                0,
                format!("ok ({n} inputs dropped since start, none in the last {period:.1} s)"),
            ),
            (true, k, n) => (
                1,
                format!("{k} inputs dropped in the last {period:.1} s ({n} since start)"),
            ),
        };
        DiagnosticStatus {
            level,
            name: name.into(),
            message,
            // diagnostic_updater requires one; the dynamics are those of this robot model.
            hardware_id: model.into(),
            values,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_groups_drops() {
        let mut h = Health::new(Logger::new("test", crate::node::logging::Level::Info));
        h.received("joint_states");
        h.dropped("joint_states", "unknown joint 'a' in name");
        h.dropped("joint_states", "unknown joint 'b' in name");
        for n in 0..50 {
            h.dropped(
                "joint_states",
                &format!("position has {n} values for 7 names"),
            );
        }
        h.dropped(
            "joint_states",
            "Deserialization { reason: \"12 bytes short\" }",
        );
        // Which joints a message lacks is detail: one counter, whatever the subset.
        let model = spatial_dynamics_core::urdf::model_from_str(
            spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF,
            &Default::default(),
        )
        .unwrap();
        let mut map = crate::joint_states::joint_map::JointMap::new(&model, &[]).unwrap();
        for first in 2..6 {
            let names: Vec<String> = (first..=7).map(|j| format!("joint{j}")).collect();
            let reason = map.match_names(&names, "name").unwrap_err();
            h.dropped("joint_states", &reason);
        }
        h.published("~/gravity_effort");
        let status = h.report("spatial_dynamics", "sd_arm7", true);
        assert_eq!(status.level, 1);
        let get = |k: &str| {
            status
                .values
                .iter()
                .find(|v| v.key == k)
                .map(|v| v.value.clone())
        };
        assert_eq!(
            get("joint_states dropped: unknown joint").as_deref(),
            Some("2")
        );
        assert_eq!(
            get("joint_states dropped: position has N values for N names").as_deref(),
            Some("50")
        );
        assert_eq!(
            get("joint_states dropped: Deserialization").as_deref(),
            Some("1")
        );
        assert_eq!(
            get("joint_states dropped: name lacks joints").as_deref(),
            Some("4")
        );
        assert_eq!(get("~/gravity_effort published").as_deref(), Some("1"));
        assert!(status.message.starts_with("57 inputs dropped in the last"));
        // A period without drops is OK again, the total still counted.
        let status = h.report("spatial_dynamics", "sd_arm7", true);
        assert_eq!(status.level, 0);
        assert!(status
            .message
            .starts_with("ok (57 inputs dropped since start, none in the last"));
        h.dropped("joint_states", "unknown joint 'c' in name");
        let status = h.report("spatial_dynamics", "sd_arm7", true);
        assert_eq!(status.level, 1);
        assert!(status.message.starts_with("1 inputs dropped in the last"));
        assert!(status.message.ends_with("(58 since start)"));
    }
}
