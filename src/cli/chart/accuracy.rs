//! Chart 2: error against time of the three forward-dynamics methods, swept over conditioning.
//!
//! Planar chains ([`reference::chain_urdf`]) of `n = 2, 4, …, 256` links with masses
//! `m_k = r^k` for mass ratios `r = 1, 10⁻², 10⁻⁴, 10⁻⁸`, while the lightest link keeps
//! `m ≥ 1e-130` (beyond, its 1e-6 spin inertia heads for the subnormals that ABA refuses). Per
//! chain, [`STATES`] seeded states: `q, q̇ ~ U(−1, 1)`, `τ_i = U(−1, 1) s_i` with
//! `s_i = g Σ_{k≥i} m_k (k − i + ½)`, the largest gravity torque joint `i` can see (as
//! `benches/conditioning.py` draws them). The error of a method is the largest over the states
//! of `‖q̈ − q̈_ref‖₂ / ‖q̈_ref‖₂` with `q̈_ref` the double-double reference
//! ([`reference::forward_dynamics`]); its time is `bench`'s median ns per call on the same model
//! ([`bench::time_kernels`], `fd_aba`, `fd_crba`, `fd_rnea_columns`).

use super::reference::{self, Chain, G};
use super::svg::{Figure, Line, Marker, Panel, Series, Style, COLORS};
use super::Table;
use crate::cli::bench::{self, Settings};
use spatial_dynamics_core::algorithms::forward_dynamics;
use spatial_dynamics_core::double_double::DoubleDouble;
use spatial_dynamics_core::sampling::Rng;
use spatial_dynamics_core::{urdf, Externals, ForwardDynamicsMethod, ModelOptions, Workspace};

/// Random states per chain.
const STATES: usize = 8;
/// Mass ratios between neighbouring links.
const RATIOS: [f64; 4] = [1.0, 1e-2, 1e-4, 1e-8];
/// The lightest link mass charted (kg).
const MIN_MASS: f64 = 1e-130;
const KERNELS: [&str; 3] = ["fd_aba", "fd_crba", "fd_rnea_columns"];

/// One (chain, method) result.
struct Point {
    n: usize,
    r: f64,
    method: ForwardDynamicsMethod,
    ns: f64,
    /// Largest and median relative error over the states; `Err` when the method refused.
    errors: Result<(f64, f64), String>,
    min_mass: f64,
}

pub fn chart(quick: bool) -> Result<(Figure, Table), String> {
    let (sizes, ratios, states): (Vec<usize>, &[f64], usize) = if quick {
        ((1..=3).map(|e| 1 << e).collect(), &[1.0, 1e-4], 2)
    } else {
        ((1..=8).map(|e| 1 << e).collect(), &RATIOS, STATES)
    };
    let mut points = Vec::new();
    for &r in ratios {
        for &n in &sizes {
            let masses = reference::geometric_masses(n, r);
            let min_mass = masses[n - 1];
            if min_mass < MIN_MASS {
                continue;
            }
            let chain = Chain::new(masses)?;
            points.extend(chain_points(&chain, r, states, quick)?);
            eprintln!("chart accuracy: n = {n}, r = {r:e} done");
        }
    }
    Ok((figure(&points, quick), table(&points)))
}

/// The seeded states of a chain: `q, q̇ ~ U(−1, 1)`, `τ_i = U(−1, 1) s_i`.
fn states(chain: &Chain, count: usize, seed: u64) -> Vec<[Vec<f64>; 3]> {
    let n = chain.len();
    let scale: Vec<f64> = (0..n)
        .map(|i| {
            G * (i..n)
                .map(|k| chain.masses[k] * ((k - i) as f64 + 0.5))
                .sum::<f64>()
        })
        .collect();
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| {
            let q = (0..n).map(|_| rng.uniform()).collect();
            let v = (0..n).map(|_| rng.uniform()).collect();
            let tau = scale.iter().map(|s| rng.uniform() * s).collect();
            [q, v, tau]
        })
        .collect()
}

fn chain_points(chain: &Chain, r: f64, count: usize, quick: bool) -> Result<Vec<Point>, String> {
    let n = chain.len();
    let model = urdf::model_from_str(&reference::chain_urdf(chain), &ModelOptions::default())
        .map_err(|e| format!("chain n = {n}, r = {r:e}: {e}"))?;
    let mut ws = Workspace::new(&model);
    let seed = (n as u64) << 32 ^ r.to_bits();
    let states = states(chain, count, seed);
    let references = states
        .iter()
        .map(|[q, v, tau]| reference::forward_dynamics(chain, q, v, tau))
        .collect::<Result<Vec<_>, _>>()?;
    let settings = if quick {
        Settings {
            states: 4,
            repeats: 1,
            min_time: 1e-3,
            baseline_instructions: false,
        }
    } else {
        Settings {
            states: (8192 / n).clamp(32, 1024),
            repeats: 3,
            min_time: 0.05,
            baseline_instructions: false,
        }
    };
    let times = bench::time_kernels(&model, &KERNELS, &settings)
        .map_err(|e| format!("chain n = {n}, r = {r:e}: {e}"))?;
    let mut points = Vec::new();
    for (method, ns) in ForwardDynamicsMethod::ALL.into_iter().zip(times) {
        let mut errors = Vec::new();
        let mut refused = None;
        for ([q, v, tau], a_ref) in states.iter().zip(&references) {
            match forward_dynamics(&model, &mut ws, q, v, tau, method, &Externals::none()) {
                Ok(a) => errors.push(relative_error(a, a_ref)),
                Err(e) => {
                    refused = Some(e.to_string());
                    break;
                }
            }
        }
        errors.sort_by(f64::total_cmp);
        points.push(Point {
            n,
            r,
            method,
            ns: ns.unwrap_or(f64::NAN),
            errors: match refused {
                Some(e) => Err(e),
                None => Ok((errors[errors.len() - 1], errors[errors.len() / 2])),
            },
            min_mass: chain.masses[n - 1],
        });
    }
    Ok(points)
}

/// `‖a − a_ref‖₂ / ‖a_ref‖₂`, the difference taken in double-double.
fn relative_error(a: &[f64], a_ref: &[DoubleDouble]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (x, y) in a.iter().zip(a_ref) {
        let d = (DoubleDouble::from(*x) - *y).to_f64();
        num += d * d;
        den += y.to_f64() * y.to_f64();
    }
    (num / den).sqrt()
}

fn table(points: &[Point]) -> Table {
    let mut table = Table::new(&[
        "n",
        "r",
        "method",
        "ns_per_call",
        "rel_err_max",
        "rel_err_median",
        "min_mass",
        "status",
    ]);
    for p in points {
        let (max, median, status) = match &p.errors {
            Ok((max, median)) => (max.to_string(), median.to_string(), "ok".to_string()),
            Err(e) => (String::new(), String::new(), format!("refused: {e}")),
        };
        table.push(vec![
            p.n.to_string(),
            format!("{:e}", p.r),
            p.method.name().into(),
            p.ns.to_string(),
            max,
            median,
            format!("{:e}", p.min_mass),
            status,
        ]);
    }
    table
}

fn ratio_label(r: f64) -> String {
    if r == 1.0 {
        "1".into()
    } else {
        format!("1e{}", r.log10().round())
    }
}

fn figure(points: &[Point], quick: bool) -> Figure {
    let ratios: Vec<f64> = points.iter().fold(Vec::new(), |mut rs, p| {
        if !rs.contains(&p.r) {
            rs.push(p.r);
        }
        rs
    });
    let mut series = Vec::new();
    let mut zeros = 0;
    for (mi, method) in ForwardDynamicsMethod::ALL.into_iter().enumerate() {
        for (ri, &r) in ratios.iter().enumerate() {
            let line: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| p.method == method && p.r == r)
                .filter_map(|p| Some((p.ns, p.errors.as_ref().ok()?.0)))
                .collect();
            zeros += line.iter().filter(|p| p.1 == 0.0).count();
            series.push(Series::new(
                format!("{}, r = {}", method.name(), ratio_label(r)),
                Style {
                    color: COLORS[mi],
                    marker: Some(Marker::ALL[ri % Marker::ALL.len()]),
                    filled: ri % 2 == 0,
                    line: Line::Solid,
                },
                line,
            ));
        }
    }
    let (t_lo, t_hi) = points
        .iter()
        .map(|p| p.ns)
        .filter(|t| t.is_finite())
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), t| {
            (lo.min(t), hi.max(t))
        });
    series.push(
        Series::reference("", vec![(t_lo, f64::EPSILON), (t_hi, f64::EPSILON)])
            .tagged("ε = 2.2e-16"),
    );
    let mut notes = Vec::new();
    for method in ForwardDynamicsMethod::ALL {
        let worst = points
            .iter()
            .filter(|p| p.method == method)
            .filter_map(|p| Some((p.errors.as_ref().ok()?.0, p.n, p.r)))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((e, n, r)) = worst {
            notes.push(format!(
                "{}: largest error {e:.1e} (n = {n}, r = {})",
                method.name(),
                ratio_label(r)
            ));
        }
        for p in points.iter().filter(|p| p.method == method) {
            if let Err(e) = &p.errors {
                notes.push(format!(
                    "{} refused n = {}, r = {}: {e}",
                    method.name(),
                    p.n,
                    ratio_label(p.r)
                ));
            }
        }
    }
    if zeros > 0 {
        notes.push(format!(
            "{zeros} points with error exactly 0 are not drawn (log axis)"
        ));
    }
    let states = if quick { 2 } else { STATES };
    Figure {
        title: "Forward dynamics: error against time per call, planar chains".into(),
        x_label: "ns per call".into(),
        y_label: "relative error of q̈ (max over states)".into(),
        panels: vec![Panel {
            title: "n = 2, 4, …, 256 links along each line, masses m_k = r^k".into(),
            series,
            notes: Vec::new(),
        }],
        columns: 1,
        legend_notes: vec![
            format!("Error: max over {states} random states of"),
            "‖q̈ − q̈_ref‖ / ‖q̈_ref‖, q̈_ref from the closed-form".into(),
            "Lagrangian in double-double (≈ 32 digits).".into(),
            format!("Chains whose lightest mass < {MIN_MASS:e} are left out."),
        ],
        notes,
        panel_size: Some((640.0, 480.0)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ABA's error on a long chain of equal links stays at a few ulps of the result: its
    /// world-frame inertias are taken about anchors a few links away, not about the root,
    /// where they would carry `m d²` terms that cancel (9.4e-13 at 128 links about the root).
    #[test]
    fn aba_keeps_its_digits_on_a_long_equal_mass_chain() {
        let chain = Chain::new(reference::geometric_masses(128, 1.0)).unwrap();
        let model =
            urdf::model_from_str(&reference::chain_urdf(&chain), &ModelOptions::default()).unwrap();
        let mut ws = Workspace::new(&model);
        for [q, v, tau] in states(&chain, 4, 7) {
            let a_ref = reference::forward_dynamics(&chain, &q, &v, &tau).unwrap();
            let method = ForwardDynamicsMethod::Aba;
            let a = forward_dynamics(&model, &mut ws, &q, &v, &tau, method, &Externals::none())
                .unwrap();
            let err = relative_error(a, &a_ref);
            assert!(err < 1e-13, "relative error {err:e}");
        }
    }
}
