//! What replay skipped or could not estimate: counts by kind, with the first occurrence of each.

use std::collections::BTreeMap;

/// One kind of problem: how often, and the first occurrence.
#[derive(Clone, Debug)]
pub struct Problem {
    pub count: u64,
    pub first_log_time: u64,
    pub first: String,
}

/// Problems by (what was affected, kind).
#[derive(Clone, Debug, Default)]
pub struct Problems {
    pub by_kind: BTreeMap<(&'static str, &'static str), Problem>,
}

impl Problems {
    pub fn add(&mut self, what: &'static str, kind: &'static str, log_time: u64, message: String) {
        self.by_kind
            .entry((what, kind))
            .and_modify(|p| p.count += 1)
            .or_insert(Problem {
                count: 1,
                first_log_time: log_time,
                first: message,
            });
    }

    pub fn merge(&mut self, other: &mut Problems) {
        for (key, p) in std::mem::take(&mut other.by_kind) {
            match self.by_kind.get_mut(&key) {
                Some(mine) => {
                    mine.count += p.count;
                    if p.first_log_time < mine.first_log_time {
                        mine.first_log_time = p.first_log_time;
                        mine.first = p.first;
                    }
                }
                None => {
                    self.by_kind.insert(key, p);
                }
            }
        }
    }

    pub fn total(&self, what: &str) -> u64 {
        self.by_kind
            .iter()
            .filter(|((w, _), _)| *w == what)
            .map(|(_, p)| p.count)
            .sum()
    }
}
