//! What replay tells when it is done: counts on stderr and (with `json`) a JSON summary on
//! stdout.

use super::pipeline::Outcome;
use super::problems::Problems;
use super::Config;
use serde_json::{json, Value};
use spatial_dynamics_core::Model;
use std::path::Path;

/// `written_to`: the output file, once it is in place (`None`: the run failed, nothing was
/// written).
#[allow(clippy::too_many_arguments)]
pub fn report(
    config: &Config,
    written_to: Option<&Path>,
    model: &Model,
    model_source: &str,
    [js_topic, cmd_topic, commands_topic]: [&str; 3],
    out_topics: &[String],
    outcome: &Outcome,
    jobs: usize,
    seconds: f64,
) {
    // Rates only from a duration the clock could measure.
    let rate = (seconds > 0.0).then(|| outcome.read[0] as f64 / seconds);
    let cpu = cpu_seconds();
    let cpu_rate = cpu.filter(|c| *c > 0.0).map(|c| outcome.read[0] as f64 / c);
    let skipped_js = outcome.problems.total("joint_states");
    let skipped_cmd = outcome.problems.total("effort_command");
    let skipped_commands = outcome.problems.total("commands");
    eprintln!(
        "spatial_dynamics replay: robot '{}' ({} coordinates) from {model_source}",
        model.name(),
        model.nv()
    );
    eprintln!(
        "read {} {js_topic}, {} {cmd_topic} and {} {commands_topic} messages in {seconds:.2} s ({}{jobs} jobs)",
        outcome.read[0],
        outcome.read[1],
        outcome.read[2],
        rate.map_or(String::new(), |r| format!("{r:.0} joint states/s, "))
    );
    let written: Vec<String> = outcome
        .written
        .iter()
        .zip(out_topics)
        .map(|(n, topic)| format!("{n} {topic}"))
        .collect();
    match written_to {
        Some(out) => eprintln!("wrote {}: {}", out.display(), written.join(", ")),
        None => eprintln!("nothing written: {}", written.join(", ")),
    }
    for (what, topic, total) in [
        ("joint_states", js_topic, skipped_js),
        ("effort_command", cmd_topic, skipped_cmd),
        ("commands", commands_topic, skipped_commands),
    ] {
        if total > 0 {
            eprintln!("skipped {total} {topic} messages:");
        }
        print_problems(&outcome.problems, what);
    }
    let missing = outcome.problems.total("measured_dynamics");
    if missing > 0 {
        eprintln!("no {} for {missing} joint states:", out_topics[2]);
        print_problems(&outcome.problems, "measured_dynamics");
    }
    let no_residual = outcome.problems.total("effort_residual");
    if no_residual > 0 {
        eprintln!(
            "no {} for {no_residual} joint states that carried effort:",
            out_topics[3]
        );
        print_problems(&outcome.problems, "effort_residual");
    }
    if outcome.log_time_backwards > 0 {
        eprintln!(
            "note: the log time went backwards {} times: messages were taken in storage order",
            outcome.log_time_backwards
        );
    }
    if config.json {
        let problems = |what: &str| -> Value {
            let mut kinds = serde_json::Map::new();
            for ((w, kind), p) in &outcome.problems.by_kind {
                if *w == what {
                    kinds.insert(
                        kind.to_string(),
                        json!({"count": p.count, "first": p.first, "first_log_time": p.first_log_time}),
                    );
                }
            }
            json!({"total": outcome.problems.total(what), "kinds": kinds})
        };
        let summary = json!({
            "model": {"name": model.name(), "nv": model.nv(), "source": model_source},
            "read": {
                js_topic: outcome.read[0],
                cmd_topic: outcome.read[1],
                commands_topic: outcome.read[2],
            },
            "out": written_to.map(|p| p.display().to_string()),
            "written": out_topics
                .iter()
                .zip(outcome.written)
                .map(|(topic, n)| (topic.clone(), json!(n)))
                .collect::<serde_json::Map<_, _>>(),
            "skipped": {
                js_topic: problems("joint_states"),
                cmd_topic: problems("effort_command"),
                commands_topic: problems("commands"),
            },
            "not_estimated": problems("measured_dynamics"),
            "no_residual": problems("effort_residual"),
            "log_time_backwards": outcome.log_time_backwards,
            "seconds": seconds,
            "joint_states_per_second": rate,
            "cpu_seconds": cpu,
            "joint_states_per_cpu_second": cpu_rate,
            "jobs": jobs,
        });
        println!("{summary}");
    }
}

/// CPU time of the whole process (every thread, user + system), from `/proc/self/stat`
/// (Linux, 100 ticks a second); `None` elsewhere.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces, inside parentheses): utime and
    // stime are the 12th and 13th.
    let rest = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: u64 = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    Some(ticks as f64 / 100.0)
}

/// One line per kind of problem with `what`: the joint names that did not match first, then
/// by count (most first).
pub fn problem_lines(problems: &Problems, what: &str) -> Vec<String> {
    let mut kinds: Vec<_> = problems
        .by_kind
        .iter()
        .filter(|((w, _), _)| *w == what)
        .collect();
    kinds.sort_by_key(|((_, kind), p)| (*kind != "bad joint names", std::cmp::Reverse(p.count)));
    kinds
        .into_iter()
        .map(|((_, kind), p)| {
            format!(
                "  {:>9}  {kind} (first at log time {}.{:09}: {})",
                p.count,
                p.first_log_time / 1_000_000_000,
                p.first_log_time % 1_000_000_000,
                p.first
            )
        })
        .collect()
}

fn print_problems(problems: &Problems, what: &str) {
    for line in problem_lines(problems, what) {
        eprintln!("{line}");
    }
}
