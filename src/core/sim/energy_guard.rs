//! The divergence guard: energy the integrator creates.
//!
//! Without contact the total energy obeys `E(t) ≤ E(0) + W(t)`, with `W(t) = ∫ Σ|τ_i q̇_i| dt`
//! the work the commands can have done (each sub-step taken at the larger of the powers at its
//! two ends, an upper bound while the power changes monotonically across it): joint damping,
//! friction and limit springs never add energy. A run whose energy exceeds that bound by more than a tolerance is creating energy and
//! is stopped. The tolerance is `max(1 J, ½ (S + W))` with `S` the energy's natural scale, the
//! largest kinetic energy seen plus the range of the potential energy seen:
//! `S = max T + (max V − min V)`. `S` does not depend on where the potential's zero lies (an arm
//! held above the world origin can start with `|E(0)| ≈ 0` while its free fall trades tens of
//! joules between `T` and `V`), and it is the size of the bounded `O(h)` energy error a stable
//! integrator shows, so only a run whose energy grows well past its own swing is stopped.
//!
//! **When the check runs.** The energy is taken once every [`ENERGY_CHECK_INTERVAL_S`] of
//! simulated time, not at every step: `E(0)` at the state the first step starts from, then, once
//! the interval has passed, at the state the next sub-step starts from (the state the last one
//! left, at its time `t`, which the error reports), before that sub-step moves it. There every
//! integrator but implicit Euler evaluates `a(q, v)` first, and with ABA (and no mimic joint)
//! the energy comes from what that evaluation leaves in the workspace, a few operations per body
//! ([`AbaEnergy`](crate::algorithms::energy::AbaEnergy)); with the `crba` or `rnea_columns`
//! method, a mimic model, implicit Euler, or an evaluation that failed, it takes a kinematics
//! pass of its own ([`energy`](crate::algorithms::energy::energy)). A run that diverges is
//! stopped at the first check after its energy passes the bound: in the step after the one that
//! ended the interval, with the state that step started from (a run whose last step ends an
//! interval has that check still to come).

use super::SimError;

/// Energy the integration may create beyond `E(0) + W(t)` at the least before the run counts as
/// diverged (J).
pub const ENERGY_TOLERANCE_J: f64 = 1.0;

/// Simulated time between two energy checks (s); a step at least this long checks every step.
pub const ENERGY_CHECK_INTERVAL_S: f64 = 0.01;

/// The energy budget of a run: its initial energy, the work done since, the scale seen.
#[derive(Clone, Debug, Default)]
pub(super) struct EnergyGuard {
    /// `E(0)`, once the first step has measured it.
    initial: Option<f64>,
    /// `W(t)` (J).
    work: f64,
    /// Simulated time since the last check (s).
    since_check: f64,
    /// Largest kinetic and smallest and largest potential energy seen at the checks (J).
    kinetic_max: f64,
    potential_min: f64,
    potential_max: f64,
}

impl EnergyGuard {
    /// Forgets the run: the next step measures `E(0)` again.
    pub(super) fn restart(&mut self) {
        *self = EnergyGuard::default();
    }

    /// Whether the energy is due at the state the next sub-step starts from: `E(0)` is still to
    /// be measured, or [`ENERGY_CHECK_INTERVAL_S`] of simulated time has passed since the last
    /// check.
    pub(super) fn due(&self) -> bool {
        self.initial.is_none() || self.since_check >= ENERGY_CHECK_INTERVAL_S * (1.0 - 1e-9)
    }

    /// Takes `(T, V)` at time `t`, when [`due`](Self::due): as `E(0)` if the run has none yet,
    /// else checked against the budget.
    pub(super) fn record(&mut self, t: f64, kinetic: f64, potential: f64) -> Result<(), SimError> {
        if self.initial.is_none() {
            self.start(kinetic, potential);
            return Ok(());
        }
        self.check(t, kinetic, potential)
    }

    /// Records the initial `(T, V)`.
    fn start(&mut self, kinetic: f64, potential: f64) {
        *self = EnergyGuard {
            initial: Some(kinetic + potential),
            kinetic_max: kinetic,
            potential_min: potential,
            potential_max: potential,
            ..Default::default()
        };
    }

    /// Adds a sub-step of length `h` under commanded power `Σ|τ_i q̇_i|` (the simulator passes
    /// the larger of its values at the sub-step's two ends).
    pub(super) fn advance(&mut self, power: f64, h: f64) {
        self.work += power * h;
        self.since_check += h;
    }

    /// Checks `(T, V)` at time `t` against the budget.
    fn check(&mut self, t: f64, kinetic: f64, potential: f64) -> Result<(), SimError> {
        self.since_check = 0.0;
        self.kinetic_max = self.kinetic_max.max(kinetic);
        self.potential_min = self.potential_min.min(potential);
        self.potential_max = self.potential_max.max(potential);
        let energy = kinetic + potential;
        let bound = self.bound(energy);
        if energy > bound {
            return Err(SimError::EnergyBlowUp {
                t,
                energy,
                bound,
                stalled: None,
            });
        }
        Ok(())
    }

    /// `E(0) + W + max(1 J, ½ (S + W))` (J).
    fn bound(&self, energy: f64) -> f64 {
        let initial = self.initial.unwrap_or(energy);
        let scale = self.kinetic_max + (self.potential_max - self.potential_min);
        initial + self.work + ENERGY_TOLERANCE_J.max(0.5 * (scale + self.work))
    }
}
