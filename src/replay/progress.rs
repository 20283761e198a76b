//! The progress line replay draws on a terminal while it runs.

use std::time::{Duration, Instant};

/// A progress line on stderr (only when it is a terminal), at most ten times a second.
pub struct Progress {
    total: Option<u64>,
    started: Instant,
    last: Instant,
}

impl Progress {
    pub fn new(total: Option<u64>) -> Progress {
        let now = Instant::now();
        Progress {
            total,
            started: now,
            last: now,
        }
    }

    pub fn tick(&mut self, done: u64) {
        if done.is_multiple_of(1024) && self.last.elapsed() >= Duration::from_millis(100) {
            self.last = Instant::now();
            self.draw(done);
        }
    }

    fn draw(&self, done: u64) {
        let elapsed = self.started.elapsed().as_secs_f64();
        let rate = match elapsed > 0.0 {
            true => format!("{:.0} msg/s", done as f64 / elapsed),
            false => String::new(),
        };
        let line = match self.total {
            Some(total) if total > 0 => {
                let fraction = (done as f64 / total as f64).min(1.0);
                let filled = (fraction * 30.0) as usize;
                format!(
                    "[{}{}] {:5.1} % {done}/{total} joint states, {}",
                    "#".repeat(filled),
                    " ".repeat(30 - filled),
                    100.0 * fraction,
                    rate
                )
            }
            _ => format!("{done} joint states, {rate}"),
        };
        eprint!("\r\x1b[2K{line}");
    }

    pub fn finish(&mut self, done: u64) {
        self.draw(done);
        eprintln!();
    }
}
