//! Passive joint forces from the URDF, each switched on or off per scene:
//!
//! - damping `τ = −d q̇` (`<dynamics damping>`),
//! - Coulomb friction, smoothed: `τ = −f tanh(q̇ / v_s)` with `v_s = 0.01` (rad/s or m/s), so the
//!   force is continuous (no chattering at rest; below `v_s` it acts as viscous `f / v_s`),
//! - effort limits: the commanded effort is clamped to `±<limit effort>` (a limit of 0 or none
//!   means unlimited), and the clamps are counted,
//! - position limits: outside `[lower, upper]` a spring–damper pushes back,
//!   `τ = −k (q − bound) − b q̇` (the damper only while moving further out), with
//!   `k = 1000 N·m/rad` (or N/m) and `b = 50`; stable for steps `h ≪ √(I/k)`.

use crate::Model;

/// Which passive forces act.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Passive {
    pub damping: bool,
    pub friction: bool,
    pub effort_limits: bool,
    pub position_limits: bool,
}

impl Passive {
    /// Everything on.
    pub fn all() -> Passive {
        Passive {
            damping: true,
            friction: true,
            effort_limits: true,
            position_limits: true,
        }
    }

    /// From names: `damping`, `friction`, `effort_limits`, `position_limits`, `all`, `none`.
    pub fn from_names<'a>(names: impl IntoIterator<Item = &'a str>) -> Result<Passive, String> {
        let mut p = Passive::default();
        for name in names {
            match name.trim() {
                "none" | "" => {}
                "all" => p = Passive::all(),
                "damping" => p.damping = true,
                "friction" => p.friction = true,
                "effort_limits" => p.effort_limits = true,
                "position_limits" => p.position_limits = true,
                other => return Err(format!("unknown passive force '{other}' (damping, friction, effort_limits, position_limits, all, none)")),
            }
        }
        Ok(p)
    }
}

/// Smoothing velocity of Coulomb friction.
pub const FRICTION_SMOOTHING: f64 = 0.01;
/// Position-limit spring stiffness and damping.
pub const LIMIT_STIFFNESS: f64 = 1000.0;
pub const LIMIT_DAMPING: f64 = 50.0;

/// Per-coordinate joint data for the passive forces (one-dof joints only).
#[derive(Clone, Debug)]
pub struct PassiveForces {
    /// `(q index, v index, limits)` of every one-dof coordinate joint.
    joints: Vec<(usize, usize, crate::model::JointLimits)>,
    /// Each velocity coordinate's effort limit (+∞ where it has none), as `clamp` takes them.
    effort_limit: Vec<f64>,
}

impl PassiveForces {
    pub fn new(model: &Model) -> PassiveForces {
        let joints = model
            .bodies
            .iter()
            .filter(|b| !b.joint.is_mimic() && b.joint.kind.nv() == 1)
            .map(|b| {
                (
                    b.joint.coords.q_index,
                    b.joint.coords.v_index,
                    b.joint.limits,
                )
            })
            .collect::<Vec<_>>();
        let mut effort_limit = vec![f64::INFINITY; model.nv];
        for &(_, vi, ref l) in &joints {
            if l.effort > 0.0 && l.effort.is_finite() {
                effort_limit[vi] = l.effort;
            }
        }
        PassiveForces {
            joints,
            effort_limit,
        }
    }

    /// `Σ |τ_i q̇_i|` over the commanded efforts as the dynamics receive them (each clamped to
    /// its limit when `effort_limits`): the most power the commands can deliver at velocities
    /// `q̇` (W).
    pub fn commanded_power(&self, effort_limits: bool, tau_cmd: &[f64], v: &[f64]) -> f64 {
        let terms = tau_cmd.iter().zip(v);
        if effort_limits {
            (terms.zip(&self.effort_limit))
                .map(|((t, v), limit)| t.abs().min(*limit) * v.abs())
                .sum()
        } else {
            terms.map(|(t, v)| (t * v).abs()).sum()
        }
    }

    /// `out = clamp(τ_cmd)`: the commanded efforts the dynamics receive, each one-dof joint's
    /// within its URDF effort limit when `on.effort_limits` (an infinite command goes to the limit
    /// of its sign, NaN stays for forward dynamics to refuse); returns how many were clamped.
    pub fn clamp_efforts(&self, on: &Passive, tau_cmd: &[f64], out: &mut [f64]) -> usize {
        out.copy_from_slice(tau_cmd);
        if !on.effort_limits {
            return 0;
        }
        let mut clamped = 0;
        for &(_, vi, ref l) in &self.joints {
            let tau = out[vi];
            if l.effort > 0.0 && l.effort.is_finite() && tau.abs() > l.effort {
                out[vi] = tau.clamp(-l.effort, l.effort);
                clamped += 1;
            }
        }
        clamped
    }

    /// `out = clamp(τ_cmd) + τ_passive(q, v)` ([`clamp_efforts`](Self::clamp_efforts));
    /// returns how many efforts were clamped.
    pub fn total(
        &self,
        on: &Passive,
        q: &[f64],
        v: &[f64],
        tau_cmd: &[f64],
        out: &mut [f64],
    ) -> usize {
        let clamped = self.clamp_efforts(on, tau_cmd, out);
        for &(qi, vi, ref l) in &self.joints {
            let mut tau = out[vi];
            let rate = v[vi];
            if on.damping {
                tau -= l.damping * rate;
            }
            if on.friction {
                tau -= l.friction * (rate / FRICTION_SMOOTHING).tanh();
            }
            if on.position_limits && l.lower < l.upper {
                let x = q[qi];
                if x < l.lower {
                    tau += LIMIT_STIFFNESS * (l.lower - x)
                        - if rate < 0.0 {
                            LIMIT_DAMPING * rate
                        } else {
                            0.0
                        };
                } else if x > l.upper {
                    tau -= LIMIT_STIFFNESS * (x - l.upper)
                        + if rate > 0.0 {
                            LIMIT_DAMPING * rate
                        } else {
                            0.0
                        };
                }
            }
            out[vi] = tau;
        }
        clamped
    }

    /// The diagonal partials of [`total`](Self::total)'s `τ_t = clamp(τ_cmd) + τ_p(q, q̇)`, each
    /// per velocity coordinate (zero, or one for `du`, where no passive force acts), by the same
    /// formulas and branches:
    ///
    /// - `du = ∂τ_t/∂τ_cmd = clamp'(τ_cmd)`: 0 for a command `total` clamps, else 1,
    /// - `dv = ∂τ_t/∂q̇ = −d − (f / v_s) (1 − tanh²(q̇ / v_s)) − b` (each term when on; `b` only
    ///   outside a position limit while moving further out),
    /// - `dq = ∂τ_t/∂q = −k` outside a position limit (0 at the bound itself, where `total`
    ///   adds no limit force).
    ///
    /// The slices are the model's `nv` long; `q`, `v` and `tau_cmd` as [`total`](Self::total)
    /// takes them.
    #[allow(clippy::too_many_arguments)]
    pub fn total_partials(
        &self,
        on: &Passive,
        q: &[f64],
        v: &[f64],
        tau_cmd: &[f64],
        dq: &mut [f64],
        dv: &mut [f64],
        du: &mut [f64],
    ) {
        dq.fill(0.0);
        dv.fill(0.0);
        du.fill(1.0);
        for &(qi, vi, ref l) in &self.joints {
            if on.effort_limits
                && l.effort > 0.0
                && l.effort.is_finite()
                && tau_cmd[vi].abs() > l.effort
            {
                du[vi] = 0.0;
            }
            let rate = v[vi];
            if on.damping {
                dv[vi] -= l.damping;
            }
            if on.friction {
                let t = (rate / FRICTION_SMOOTHING).tanh();
                dv[vi] -= l.friction / FRICTION_SMOOTHING * (1.0 - t * t);
            }
            if on.position_limits && l.lower < l.upper {
                let x = q[qi];
                let outward = (x < l.lower && rate < 0.0) || (x > l.upper && rate > 0.0);
                if x < l.lower || x > l.upper {
                    dq[vi] -= LIMIT_STIFFNESS;
                }
                if outward {
                    dv[vi] -= LIMIT_DAMPING;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passive_forces_by_name() {
        assert_eq!(
            Passive::from_names(["damping", " friction"]).unwrap(),
            Passive {
                damping: true,
                friction: true,
                ..Default::default()
            }
        );
        assert_eq!(Passive::from_names(["all"]).unwrap(), Passive::all());
        assert_eq!(Passive::from_names(["none"]).unwrap(), Passive::default());
        assert!(Passive::from_names(["springs"])
            .unwrap_err()
            .contains("'springs'"));
    }
}
