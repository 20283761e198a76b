//! The divergence guard: energy the integrator creates.
//!
//! Without contact the total energy obeys `E(t) ≤ E(0) + W(t)`, with `W(t) = ∫ Σ|τ_i q̇_i| dt`
//! the work the commands can have done: joint damping, friction and limit springs never add
//! energy. A run whose energy exceeds that bound by more than a tolerance is creating energy and
//! is stopped. The tolerance is `max(1 J, ½ (S + W))` with `S` the energy's natural scale, the
//! largest kinetic energy seen plus the range of the potential energy seen:
//! `S = max T + (max V − min V)`. `S` does not depend on where the potential's zero lies (an arm
//! held above the world origin can start with `|E(0)| ≈ 0` while its free fall trades tens of
//! joules between `T` and `V`), and it is the size of the bounded `O(h)` energy error a stable
//! integrator shows, so only a run whose energy grows well past its own swing is stopped.
//!
//! The energy takes a kinematics pass, so the guard evaluates it once every
//! [`ENERGY_CHECK_INTERVAL_S`] of simulated time (and `E(0)` before the first step), not at every
//! step; a run that diverges is stopped at the first check after its energy passes the bound.

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

    /// Whether `E(0)` is still to be measured.
    pub(super) fn needs_initial(&self) -> bool {
        self.initial.is_none()
    }

    /// Records the initial `(T, V)`.
    pub(super) fn start(&mut self, kinetic: f64, potential: f64) {
        *self = EnergyGuard {
            initial: Some(kinetic + potential),
            kinetic_max: kinetic,
            potential_min: potential,
            potential_max: potential,
            ..Default::default()
        };
    }

    /// Adds a sub-step of length `h` under commanded power `Σ|τ_i q̇_i|`; returns whether the
    /// energy is due for a check.
    pub(super) fn advance(&mut self, power: f64, h: f64) -> bool {
        self.work += power * h;
        self.since_check += h;
        self.since_check >= ENERGY_CHECK_INTERVAL_S * (1.0 - 1e-9)
    }

    /// Checks `(T, V)` at time `t` against the budget.
    pub(super) fn check(&mut self, t: f64, kinetic: f64, potential: f64) -> Result<(), SimError> {
        self.since_check = 0.0;
        self.kinetic_max = self.kinetic_max.max(kinetic);
        self.potential_min = self.potential_min.min(potential);
        self.potential_max = self.potential_max.max(potential);
        let energy = kinetic + potential;
        let bound = self.bound(energy);
        if energy > bound {
            return Err(SimError::EnergyBlowUp { t, energy, bound });
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
