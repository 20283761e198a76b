//! `spatial_dynamics chart --out DIR`: regenerates the three charts of the README, each an SVG
//! drawn by [`svg`] and the CSV behind it.
//!
//! | file | what |
//! |---|---|
//! | `timing.svg`, `timing.csv` | ns per call of every `bench` kernel against nv: pendulum chains of 1…256 links and the `--robot`s, ours and (with `--pinocchio-bench`) Pinocchio's, with O(n), O(n²), O(n³) slopes ([`timing`]) |
//! | `accuracy.svg`, `accuracy.csv` | error against time of the three forward-dynamics methods on planar chains swept over length and mass ratio, against a double-double reference ([`accuracy`], [`reference`]) |
//! | `work_precision.svg`, `work_precision.csv` | error at the final time against CPU time per simulated second of the four integrators over a sweep of steps ([`work_precision`]) |
//! | `urdf/` | the chain URDFs both benches read |
//!
//! `--quick` shrinks every sweep and timing so the whole command takes seconds (for tests); the
//! numbers are then not worth plotting.

mod accuracy;
mod reference;
mod svg;
mod timing;
mod work_precision;

use clap::Args;
use serde_json::{json, Value};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The three charts, by the names `--only` takes and their files carry.
const CHARTS: [&str; 3] = ["timing", "accuracy", "work_precision"];

/// Options of `chart`.
#[derive(Args, Debug)]
pub struct ChartArgs {
    /// Output directory (created if missing): <chart>.svg and <chart>.csv for timing, accuracy
    /// and work_precision, and urdf/ with the chain URDFs.
    #[arg(long, value_name = "DIR", required_unless_present = "reference_eval")]
    out: Option<PathBuf>,
    /// Small sweeps and millisecond timings (seconds in all), for tests: not for reading.
    #[arg(long)]
    quick: bool,
    /// A robot for the timing chart, NAME=PATH[,floating] (repeatable). Mimic joints are made
    /// independent, as Pinocchio's URDF parser has them.
    #[arg(long = "robot", value_name = "NAME=PATH[,floating]")]
    robots: Vec<String>,
    /// Pinocchio's bench (benches/pinocchio/bench.cpp, built by
    /// launch_scripts/bench_pinocchio.sh --build-only): timed on the same URDFs in the same run.
    #[arg(long, value_name = "BIN")]
    pinocchio_bench: Option<PathBuf>,
    /// Only these charts (comma-separated): timing, accuracy, work_precision.
    #[arg(long, value_name = "CHART", value_delimiter = ',')]
    only: Vec<String>,
    /// Serve the double-double chain reference instead: one JSON request per stdin line,
    /// {"masses": [..], "q": [..], "v": [..], "tau": [..]} → {"a_hi": [..], "a_lo": [..]}.
    #[arg(long, hide = true, conflicts_with_all = ["out", "quick", "robots", "pinocchio_bench", "only"])]
    reference_eval: bool,
}

/// Runs the charts asked for.
pub fn run(args: &ChartArgs) -> Result<(), String> {
    if args.reference_eval {
        return reference_eval();
    }
    let out = args.out.as_deref().ok_or("--out DIR is required")?;
    for name in &args.only {
        if !CHARTS.contains(&name.as_str()) {
            return Err(format!(
                "--only {name}: unknown chart (use {})",
                CHARTS.join(", ")
            ));
        }
    }
    let robots = args
        .robots
        .iter()
        .map(|spec| spec.parse::<timing::Robot>())
        .collect::<Result<Vec<_>, _>>()?;
    if let Some(bin) = &args.pinocchio_bench {
        if !bin.is_file() {
            return Err(format!("--pinocchio-bench {}: no such file", bin.display()));
        }
    }
    // Every --robot is loaded before anything is timed or written.
    let robots = robots
        .into_iter()
        .map(|robot| robot.load().map(|model| (robot, model)))
        .collect::<Result<Vec<_>, _>>()?;
    let wanted = |name: &str| args.only.is_empty() || args.only.iter().any(|o| o == name);
    let charts: Vec<&str> = CHARTS.into_iter().filter(|n| wanted(n)).collect();
    let mut outputs: Vec<PathBuf> = Vec::new();
    for name in &charts {
        outputs.push(format!("{name}.svg").into());
        outputs.push(format!("{name}.csv").into());
        if *name == "timing" {
            outputs.extend(timing::urdf_outputs(args.quick));
        }
    }
    for rel in &outputs {
        check_destination(out, rel)?;
    }
    let made_out = !out.exists();
    std::fs::create_dir_all(out).map_err(|e| format!("--out {}: {e}", out.display()))?;
    let result = make_charts(out, &charts, &robots, args);
    if result.is_err() && made_out {
        // Only removes the directory when it is empty, as this run left it.
        let _ = std::fs::remove_dir(out);
    }
    for line in result? {
        println!("{line}");
    }
    Ok(())
}

/// Draws `charts` into a [`Staging`] directory in `out` and moves them into place once all
/// succeeded; the lines to print.
fn make_charts(
    out: &Path,
    charts: &[&str],
    robots: &[(timing::Robot, spatial_dynamics_core::Model)],
    args: &ChartArgs,
) -> Result<Vec<String>, String> {
    let mut staging = Staging::new(out)?;
    let mut report = Vec::new();
    for name in charts {
        let start = Instant::now();
        let (figure, table) = match *name {
            "timing" => timing::chart(
                &mut staging,
                robots,
                args.pinocchio_bench.as_deref(),
                args.quick,
            )?,
            "accuracy" => accuracy::chart(args.quick)?,
            _ => work_precision::chart(args.quick)?,
        };
        let svg = PathBuf::from(format!("{name}.svg"));
        staging.write(&svg, &figure.to_svg())?;
        let csv = PathBuf::from(format!("{name}.csv"));
        staging.write(&csv, &table.to_csv())?;
        report.push(format!(
            "{name}: wrote {} and {} ({} rows) in {:.1} s",
            out.join(svg).display(),
            out.join(csv).display(),
            table.rows.len(),
            start.elapsed().as_secs_f64()
        ));
        report.extend(figure.notes.iter().map(|note| format!("  {note}")));
    }
    staging.commit()?;
    Ok(report)
}

/// `out/rel` can be written by a rename: neither it nor a directory on the way to it is anything
/// but what it must be (a file, or a directory, or missing).
fn check_destination(out: &Path, rel: &Path) -> Result<(), String> {
    let dest = out.join(rel);
    if dest.is_dir() {
        return Err(format!("{}: is a directory", dest.display()));
    }
    let mut dir = dest.parent();
    while let Some(d) = dir.filter(|d| d.starts_with(out) && *d != out) {
        if d.exists() && !d.is_dir() {
            return Err(format!("{}: not a directory", d.display()));
        }
        dir = d.parent();
    }
    Ok(())
}

/// The outputs of one run, written into a hidden directory inside the output directory (the
/// same file system, so a rename moves them) and moved into place together by
/// [`Staging::commit`]; dropped uncommitted, it removes what it wrote.
pub struct Staging {
    out: PathBuf,
    dir: PathBuf,
    /// The files written, relative to `dir` and to `out` alike.
    files: Vec<PathBuf>,
}

impl Staging {
    fn new(out: &Path) -> Result<Staging, String> {
        let dir = out.join(format!(".chart-{}.tmp", std::process::id()));
        // A directory of this name is a leftover of a killed run with the same process id.
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        Ok(Staging {
            out: out.to_path_buf(),
            dir,
            files: Vec::new(),
        })
    }

    /// Writes `text` to the staged copy of `out/rel`; the path written.
    pub fn write(&mut self, rel: &Path, text: &str) -> Result<PathBuf, String> {
        let path = self.dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
        }
        std::fs::write(&path, text)
            .map_err(|e| format!("{}: {e}", self.out.join(rel).display()))?;
        if !self.files.iter().any(|f| f == rel) {
            self.files.push(rel.to_path_buf());
        }
        Ok(path)
    }

    /// Renames every staged file over its destination. A file already there is first moved
    /// aside, so that when one rename fails the earlier ones are undone and every destination
    /// is as it was.
    fn commit(self) -> Result<(), String> {
        for rel in &self.files {
            check_destination(&self.out, rel)?;
        }
        let old = self.dir.join(".old");
        let mut done: Vec<(&PathBuf, bool)> = Vec::new();
        let mut result = Ok(());
        for rel in &self.files {
            let (staged, dest, aside) = (self.dir.join(rel), self.out.join(rel), old.join(rel));
            let had_old = dest.symlink_metadata().is_ok();
            let step = || -> std::io::Result<()> {
                if let Some(parent) = dest.parent() {
                    std::fs::create_dir_all(parent)?;
                }
                if had_old {
                    std::fs::create_dir_all(aside.parent().unwrap_or(&old))?;
                    std::fs::rename(&dest, &aside)?;
                }
                std::fs::rename(&staged, &dest)
            };
            if let Err(e) = step() {
                if had_old && aside.symlink_metadata().is_ok() {
                    let _ = std::fs::rename(&aside, &dest);
                }
                result = Err(format!("{}: {e}", dest.display()));
                break;
            }
            done.push((rel, had_old));
        }
        if result.is_err() {
            for (rel, had_old) in done.into_iter().rev() {
                let dest = self.out.join(rel);
                let _ = if had_old {
                    std::fs::rename(old.join(rel), &dest)
                } else {
                    std::fs::remove_file(&dest)
                };
            }
        }
        // `self` is dropped here, which removes the staging directory and the old files.
        result
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Rows of text cells under a header; written as CSV (cells with a comma or quote quoted).
#[derive(Debug, Default)]
pub struct Table {
    pub header: Vec<&'static str>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new(header: &[&'static str]) -> Table {
        Table {
            header: header.to_vec(),
            rows: Vec::new(),
        }
    }

    /// Appends a row; it must have one cell per column.
    pub fn push(&mut self, row: Vec<String>) {
        debug_assert_eq!(row.len(), self.header.len());
        self.rows.push(row);
    }

    pub fn to_csv(&self) -> String {
        let cell = |c: &str| {
            if c.contains([',', '"', '\n']) {
                format!("\"{}\"", c.replace('"', "\"\""))
            } else {
                c.to_string()
            }
        };
        let mut out = self.header.join(",") + "\n";
        for row in &self.rows {
            out += &row.iter().map(|c| cell(c)).collect::<Vec<_>>().join(",");
            out.push('\n');
        }
        out
    }
}

/// The least-squares slope of `log y` against `log x` (the exponent of a power law), or `None`
/// with fewer than two usable points.
pub fn log_slope(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let (mx, my) = logs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxy: f64 = logs.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = logs.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// The hidden `--reference-eval` loop: the double-double reference of [`reference`], for the
/// Python test against mpmath. Each answer gives `a = a_hi + a_lo` (two doubles per joint).
fn reference_eval() -> Result<(), String> {
    let stdin = std::io::stdin();
    let mut stdout = std::io::stdout().lock();
    for line in stdin.lock().lines() {
        let line = line.map_err(|e| format!("stdin: {e}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let answer = match answer_reference(&line) {
            Ok(a) => json!({
                "a_hi": a.iter().map(|x| x.hi).collect::<Vec<_>>(),
                "a_lo": a.iter().map(|x| x.lo).collect::<Vec<_>>(),
            }),
            Err(e) => json!({ "error": e }),
        };
        writeln!(stdout, "{answer}").map_err(|e| format!("stdout: {e}"))?;
        stdout.flush().map_err(|e| format!("stdout: {e}"))?;
    }
    Ok(())
}

fn answer_reference(
    line: &str,
) -> Result<Vec<spatial_dynamics_core::double_double::DoubleDouble>, String> {
    let request: Value = serde_json::from_str(line).map_err(|e| format!("bad JSON: {e}"))?;
    let numbers = |key: &str| -> Result<Vec<f64>, String> {
        request[key]
            .as_array()
            .ok_or(format!("'{key}' must be an array of numbers"))?
            .iter()
            .map(|x| x.as_f64().ok_or(format!("'{key}' must hold numbers only")))
            .collect()
    };
    let chain = reference::Chain::new(numbers("masses")?)?;
    reference::forward_dynamics(&chain, &numbers("q")?, &numbers("v")?, &numbers("tau")?)
}
