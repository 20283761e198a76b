//! Chart 1: time per call against the number of degrees of freedom, every kernel `bench` times.
//!
//! Models: planar pendulum chains of 1, 2, 4, …, 256 links
//! ([`examples::pendulum_urdf`], 1 m, 1 kg, written to `DIR/urdf/pendulum<n>.urdf`) and the
//! `--robot`s (mimic joints independent). Ours is timed by `bench`'s own code
//! ([`bench::time_kernels`]); with `--pinocchio-bench` Pinocchio's bench runs right after ours on
//! the same URDF file with the same states count, repeats and minimum repeat time. The number of
//! random states falls with nv (`8192 / nv`, within 32…1024) so the long chains' O(n³) kernels stay
//! within seconds.
//!
//! Reference slopes O(n), O(n²), O(n³) pass through our time at the longest chain.

use super::svg::{Figure, Line, Marker, Panel, Series, Style, COLORS};
use super::{log_slope, Staging, Table};
use crate::cli::bench::{self, Settings, KERNELS};
use serde_json::Value;
use spatial_dynamics_core::model::examples;
use spatial_dynamics_core::{urdf, Model, ModelOptions};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::str::FromStr;

/// A `--robot NAME=PATH[,floating]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Robot {
    pub name: String,
    pub path: PathBuf,
    pub floating: bool,
}

impl FromStr for Robot {
    type Err = String;
    fn from_str(spec: &str) -> Result<Robot, String> {
        let bad = || format!("--robot '{spec}': expected NAME=PATH or NAME=PATH,floating");
        let (name, rest) = spec.split_once('=').ok_or_else(bad)?;
        let (path, floating) = match rest.strip_suffix(",floating") {
            Some(path) => (path, true),
            None => (rest, false),
        };
        if name.trim().is_empty() || path.is_empty() || name.contains(',') {
            return Err(bad());
        }
        Ok(Robot {
            name: name.trim().to_string(),
            path: PathBuf::from(path),
            floating,
        })
    }
}

impl Robot {
    /// The model the timing chart times (mimic joints independent); the error names the
    /// `--robot`.
    pub fn load(&self) -> Result<Model, String> {
        let options = ModelOptions {
            floating_base: self.floating,
            ignore_mimic: true,
            ..ModelOptions::default()
        };
        let model = urdf::model_from_file(&self.path, &options)
            .map_err(|e| format!("--robot {}={}: {e}", self.name, self.path.display()))?;
        settings(model.nv(), false)
            .check_memory(&model)
            .map_err(|e| format!("--robot {}: {e}", self.name))?;
        Ok(model)
    }
}

/// The chain lengths timed: 1, 2, 4, …, 256 links (…, 8 with `quick`).
fn chain_lengths(quick: bool) -> impl Iterator<Item = usize> {
    let max_exp = if quick { 3 } else { 8 };
    (0..=max_exp).map(|e| 1usize << e)
}

/// The chain URDFs the chart writes, relative to the output directory.
pub fn urdf_outputs(quick: bool) -> Vec<PathBuf> {
    chain_lengths(quick).map(chain_urdf).collect()
}

fn chain_urdf(n: usize) -> PathBuf {
    Path::new("urdf").join(format!("pendulum{n}.urdf"))
}

/// One model's times: ours and Pinocchio's, ns per call per kernel (in [`KERNELS`] order).
struct Timed {
    name: String,
    chain: bool,
    nv: usize,
    states: usize,
    ours: Vec<Option<f64>>,
    pinocchio: Option<Vec<Option<f64>>>,
}

/// Timing settings for a model with `nv` coordinates.
fn settings(nv: usize, quick: bool) -> Settings {
    if quick {
        return Settings {
            states: 4,
            repeats: 1,
            min_time: 1e-3,
            baseline_instructions: false,
        };
    }
    Settings {
        states: (8192 / nv.max(1)).clamp(32, 1024),
        repeats: 5,
        min_time: 0.1,
        baseline_instructions: false,
    }
}

/// The chart and its table; the chain URDFs are written through `staging` (Pinocchio's bench
/// reads them from there), `robots` are the `--robot`s, already loaded by [`Robot::load`].
pub fn chart(
    staging: &mut Staging,
    robots: &[(Robot, Model)],
    pinocchio: Option<&Path>,
    quick: bool,
) -> Result<(Figure, Table), String> {
    let mut timed = Vec::new();
    for n in chain_lengths(quick) {
        let text = examples::pendulum_urdf(n, 1.0, 1.0);
        let path = staging.write(&chain_urdf(n), &text)?;
        let name = format!("pendulum{n}");
        let model = urdf::model_from_str(&text, &ModelOptions::default())
            .map_err(|e| format!("{name}: {e}"))?;
        let spec = Robot {
            name,
            path,
            floating: false,
        };
        timed.push(time_model(&spec, &model, true, pinocchio, quick)?);
    }
    for (robot, model) in robots {
        timed.push(time_model(robot, model, false, pinocchio, quick)?);
    }
    Ok((figure(&timed, pinocchio.is_some()), table(&timed)))
}

fn time_model(
    spec: &Robot,
    model: &Model,
    chain: bool,
    pinocchio: Option<&Path>,
    quick: bool,
) -> Result<Timed, String> {
    let settings = settings(model.nv(), quick);
    let ours = bench::time_kernels(model, &KERNELS, &settings)
        .map_err(|e| format!("{}: {e}", spec.name))?;
    let pinocchio = pinocchio
        .map(|bin| run_pinocchio(bin, spec, &settings, model.nv()))
        .transpose()?;
    eprintln!("chart timing: {} (nv = {}) done", spec.name, model.nv());
    Ok(Timed {
        name: spec.name.clone(),
        chain,
        nv: model.nv(),
        states: settings.states,
        ours,
        pinocchio,
    })
}

/// Runs `bin URDF [--floating-base] --states N --repeats N --min-time S` and reads its JSON
/// `{"nv", "ns_per_call": {kernel: ns}}`.
fn run_pinocchio(
    bin: &Path,
    spec: &Robot,
    settings: &Settings,
    nv: usize,
) -> Result<Vec<Option<f64>>, String> {
    let mut command = Command::new(bin);
    command.arg(&spec.path);
    if spec.floating {
        command.arg("--floating-base");
    }
    command.args([
        "--states",
        &settings.states.to_string(),
        "--repeats",
        &settings.repeats.to_string(),
        "--min-time",
        &settings.min_time.to_string(),
    ]);
    let what = format!("{} on {}", bin.display(), spec.name);
    let output = command.output().map_err(|e| format!("{what}: {e}"))?;
    if !output.status.success() {
        return Err(format!(
            "{what} failed ({}): {}",
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    let text = String::from_utf8_lossy(&output.stdout);
    let json: Value = serde_json::from_str(text.trim())
        .map_err(|e| format!("{what}: its output is not the bench JSON ({e}): {text}"))?;
    if json["nv"].as_u64() != Some(nv as u64) {
        eprintln!(
            "chart timing: warning: {}: Pinocchio's nv is {} and ours {nv}",
            spec.name, json["nv"]
        );
    }
    Ok(KERNELS
        .iter()
        .map(|k| json["ns_per_call"][k].as_f64())
        .collect())
}

fn table(timed: &[Timed]) -> Table {
    let mut table = Table::new(&[
        "model",
        "kind",
        "nv",
        "library",
        "algorithm",
        "ns_per_call",
        "states",
    ]);
    for t in timed {
        let libraries =
            std::iter::once(("ours", &t.ours)).chain(t.pinocchio.iter().map(|p| ("pinocchio", p)));
        for (library, times) in libraries {
            for (kernel, ns) in KERNELS.iter().zip(times) {
                // A kernel the library refuses (ABA with mimic joints) has no row.
                if let Some(ns) = ns {
                    table.push(vec![
                        t.name.clone(),
                        if t.chain { "chain" } else { "robot" }.into(),
                        t.nv.to_string(),
                        library.into(),
                        kernel.to_string(),
                        ns.to_string(),
                        t.states.to_string(),
                    ]);
                }
            }
        }
    }
    table
}

fn figure(timed: &[Timed], with_pinocchio: bool) -> Figure {
    let style = |color, marker, filled, line| Style {
        color,
        marker: Some(marker),
        filled,
        line,
    };
    let points = |chain: bool, k: usize, pin: bool| -> Vec<(f64, f64)> {
        timed
            .iter()
            .filter(|t| t.chain == chain)
            .filter_map(|t| {
                let times = if pin { t.pinocchio.as_ref()? } else { &t.ours };
                Some((t.nv as f64, times[k]?))
            })
            .collect()
    };
    let mut panels = Vec::new();
    let mut notes = Vec::new();
    for (k, kernel) in KERNELS.iter().enumerate() {
        let ours_chain = points(true, k, false);
        let mut series = vec![
            Series::new(
                "ours: pendulum chains",
                style(COLORS[0], Marker::Circle, true, Line::Solid),
                ours_chain.clone(),
            ),
            Series::new(
                "ours: robots",
                style(COLORS[0], Marker::Diamond, true, Line::None),
                points(false, k, false),
            ),
        ];
        if with_pinocchio {
            series.push(Series::new(
                "Pinocchio: pendulum chains",
                style(COLORS[1], Marker::Circle, false, Line::Solid),
                points(true, k, true),
            ));
            series.push(Series::new(
                "Pinocchio: robots",
                style(COLORS[1], Marker::Diamond, false, Line::None),
                points(false, k, true),
            ));
        }
        // O(n^p) through our longest chain, from there down to n = 1.
        if let Some(&(n_max, t_max)) = ours_chain.last() {
            for (p, label) in [(1, "O(n)"), (2, "O(n²)"), (3, "O(n³)")] {
                let line = (0..=32)
                    .map(|i| n_max.powf(1.0 - f64::from(i) / 32.0))
                    .map(|n| (n, t_max * (n / n_max).powi(p)))
                    .collect();
                series.push(Series::reference("O(n), O(n²), O(n³)", line).tagged(label));
            }
        }
        let mut panel_notes = Vec::new();
        let long: Vec<(f64, f64)> = ours_chain.iter().copied().filter(|p| p.0 >= 32.0).collect();
        if let Some(slope) = log_slope(&long) {
            panel_notes.push(format!("ours, n = 32…256: slope {slope:.2}"));
            notes.push(format!(
                "{kernel}: ours grows as n^{slope:.2} on chains of 32…256 links"
            ));
        }
        let long_pin: Vec<(f64, f64)> = points(true, k, true)
            .into_iter()
            .filter(|p| p.0 >= 32.0)
            .collect();
        if let Some(slope) = log_slope(&long_pin) {
            panel_notes.push(format!("Pinocchio: slope {slope:.2}"));
        }
        panels.push(Panel {
            title: kernel.to_string(),
            series,
            notes: panel_notes,
        });
    }
    let mut robots: Vec<&Timed> = timed.iter().filter(|t| !t.chain).collect();
    robots.sort_by_key(|t| t.nv);
    let mut legend_notes = vec![
        "Chains: planar pendulums of 1 m, 1 kg rods.".to_string(),
        "Robots (nv):".to_string(),
    ];
    legend_notes.extend(robots.iter().map(|t| format!("· {} ({})", t.name, t.nv)));
    legend_notes.push("Median of repeats over random states;".into());
    legend_notes.push("one thread, shared 2-core machine.".into());
    Figure {
        title: "Time per call against degrees of freedom".into(),
        x_label: "degrees of freedom nv".into(),
        y_label: "ns per call".into(),
        panels,
        columns: 3,
        legend_notes,
        notes,
        panel_size: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robot_specs_parse() {
        assert_eq!(
            "UR5=/a/ur5.urdf".parse::<Robot>().unwrap(),
            Robot {
                name: "UR5".into(),
                path: "/a/ur5.urdf".into(),
                floating: false
            }
        );
        assert!(
            "Solo=/b/solo.urdf,floating"
                .parse::<Robot>()
                .unwrap()
                .floating
        );
        assert!("nopath".parse::<Robot>().unwrap_err().contains("nopath"));
        assert!("=x.urdf".parse::<Robot>().is_err());
        assert!("a=".parse::<Robot>().is_err());
    }
}
