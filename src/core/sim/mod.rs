//! Simulation: integrate forward dynamics in time under commanded efforts and the passive joint
//! forces a scene asks for (damping, friction, effort and position limits).
//!
//! One [`Simulator::step`] advances `(t, q, v)` by `dt` in `substeps` equal sub-steps with the
//! chosen [`Integrator`] and forward-dynamics method. Configurations move on their manifold
//! ([`Model::integrate`]: quaternions by the exponential map, renormalised). A step that cannot be
//! trusted stops with a [`SimError`] saying when and why: non-finite state (checked every
//! sub-step), energy blow-up (checked every [`ENERGY_CHECK_INTERVAL_S`] of simulated time, see
//! [`energy_guard`]), singular mass matrix. A [`Servo`] turns position or velocity commands into the efforts of
//! each step.

mod configuration;
mod contact;
mod energy_guard;
mod forces;
mod integrator;
mod servo;

use configuration::Configuration;
use contact::Contacts;
pub use contact::{ContactPoint, Ground};
use energy_guard::EnergyGuard;
pub use energy_guard::{ENERGY_CHECK_INTERVAL_S, ENERGY_TOLERANCE_J};
pub use forces::{Passive, PassiveForces};
pub use integrator::Integrator;
pub use servo::{CommandInterface, Servo, ServoAxis};

use crate::algorithms::validate::all_finite;
use crate::algorithms::{energy, forward_dynamics};
use crate::error::DynamicsError;
use crate::{Externals, ForwardDynamicsMethod, Model, Workspace};
use nalgebra::{DMatrix, DVector};
use std::fmt;

/// How a simulation runs.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    pub integrator: Integrator,
    pub method: ForwardDynamicsMethod,
    /// Step (s), split into `substeps` equal sub-steps.
    pub dt: f64,
    pub substeps: usize,
    pub passive: Passive,
    /// Ground contact, for scenes that need it.
    pub ground: Option<Ground>,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            integrator: Integrator::SemiImplicitEuler,
            method: ForwardDynamicsMethod::Aba,
            dt: 1e-3,
            substeps: 1,
            passive: Passive::default(),
            ground: None,
        }
    }
}

/// The simulated state.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Time (s).
    pub t: f64,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
}

impl State {
    /// At rest at `q`, time zero.
    pub fn at_rest(model: &Model, q: Vec<f64>) -> State {
        State {
            t: 0.0,
            q,
            v: vec![0.0; model.nv],
        }
    }
}

/// Why a simulation stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// Forward dynamics failed (singular mass matrix, bad input, …).
    Dynamics { t: f64, source: DynamicsError },
    /// The state stopped being finite.
    NonFinite { t: f64, coordinate: String },
    /// The energy grew beyond what the initial energy and the work of the commands allow.
    EnergyBlowUp { t: f64, energy: f64, bound: f64 },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Dynamics { t, source } => write!(f, "at t = {t:.6} s: {source}"),
            SimError::NonFinite { t, coordinate } => write!(f, "at t = {t:.6} s: the state of '{coordinate}' is no longer finite"),
            SimError::EnergyBlowUp { t, energy, bound } => write!(
                f,
                "at t = {t:.6} s: the energy rose to {energy:.6e} J, above {bound:.6e} J (the initial energy plus the work of the commands plus a tolerance): the integrator is creating energy"
            ),
        }
    }
}

impl std::error::Error for SimError {}

/// Forward dynamics with the passive forces added: `a(q, v) = FD(q, v, clamp(τ_cmd) + τ_passive)`.
pub(crate) struct Evaluator {
    ws: Workspace,
    passive: PassiveForces,
    tau: Vec<f64>,
    method: ForwardDynamicsMethod,
    on: Passive,
    contacts: Option<Contacts>,
    /// Effort evaluations clamped to their limits.
    clamped: u64,
}

impl Evaluator {
    /// `q̈` at `(q, v)` under `tau_cmd`, into `out`.
    pub(crate) fn acceleration(
        &mut self,
        model: &Model,
        q: &[f64],
        v: &[f64],
        tau_cmd: &[f64],
        out: &mut [f64],
    ) -> Result<(), DynamicsError> {
        // With no passive force on, the commanded efforts go to the dynamics as they are.
        let tau: &[f64] = if self.on == Passive::default() {
            tau_cmd
        } else {
            self.clamped += self.passive.total(&self.on, q, v, tau_cmd, &mut self.tau) as u64;
            &self.tau
        };
        let wrenches = match &mut self.contacts {
            Some(c) if !c.is_empty() => Some(c.wrenches(model, &mut self.ws, q, v)?),
            _ => None,
        };
        let ext = Externals {
            wrenches,
            ..Default::default()
        };
        let a = forward_dynamics(model, &mut self.ws, q, v, tau, self.method, &ext)?;
        out.copy_from_slice(a);
        Ok(())
    }
}

/// Per-step scratch vectors of the integrators.
pub(crate) struct Scratch {
    /// How `q ⊕ v·dt` moves each coordinate ([`Configuration`]).
    configuration: Configuration,
    /// Stage velocities and accelerations (RK4 uses four of each).
    k_v: [Vec<f64>; 4],
    k_a: [Vec<f64>; 4],
    q_stage: Vec<f64>,
    v_stage: Vec<f64>,
    /// Implicit Euler: Newton matrix, residual, probes.
    jacobian: DMatrix<f64>,
    residual: DVector<f64>,
    q_probe: Vec<f64>,
    a_probe: Vec<f64>,
}

/// A simulator for one model and configuration; [`step`](Self::step) allocates nothing.
pub struct Simulator {
    pub config: SimConfig,
    eval: Evaluator,
    scratch: Scratch,
    guard: EnergyGuard,
}

impl Simulator {
    /// A simulator for `model`; fails when a contact point names a link the model lacks.
    pub fn new(model: &Model, config: SimConfig) -> Result<Simulator, String> {
        let contacts = config
            .ground
            .as_ref()
            .map(|g| Contacts::new(model, g))
            .transpose()?;
        let (nq, nv) = (model.nq, model.nv);
        let vecs = || [vec![0.0; nv], vec![0.0; nv], vec![0.0; nv], vec![0.0; nv]];
        Ok(Simulator {
            eval: Evaluator {
                ws: Workspace::new(model),
                passive: PassiveForces::new(model),
                tau: vec![0.0; nv],
                method: config.method,
                on: config.passive,
                contacts,
                clamped: 0,
            },
            scratch: Scratch {
                configuration: Configuration::new(model),
                k_v: vecs(),
                k_a: vecs(),
                q_stage: vec![0.0; nq],
                v_stage: vec![0.0; nv],
                jacobian: DMatrix::zeros(nv, nv),
                residual: DVector::zeros(nv),
                q_probe: vec![0.0; nq],
                a_probe: vec![0.0; nv],
            },
            config,
            guard: EnergyGuard::default(),
        })
    }

    /// The state was set from outside (a reset): the energy budget of the divergence check
    /// starts again from the state of the next step.
    pub fn restart_energy_budget(&mut self) {
        self.guard.restart();
    }

    /// Deepest ground penetration of any contact point so far (m).
    pub fn max_penetration(&self) -> f64 {
        self.eval
            .contacts
            .as_ref()
            .map_or(0.0, |c| c.max_penetration)
    }

    /// How many effort evaluations were clamped to their limits so far.
    pub fn clamped(&self) -> u64 {
        self.eval.clamped
    }

    /// Total energy `T + V` at a state (J).
    pub fn energy(&mut self, model: &Model, state: &State) -> Result<f64, SimError> {
        let (kinetic, potential) = self.kinetic_and_potential(model, state)?;
        Ok(kinetic + potential)
    }

    /// `(T, V)` at a state (J).
    fn kinetic_and_potential(
        &mut self,
        model: &Model,
        state: &State,
    ) -> Result<(f64, f64), SimError> {
        energy(model, &mut self.eval.ws, &state.q, &state.v)
            .map_err(|source| SimError::Dynamics { t: state.t, source })
    }

    /// Advances `state` by `dt` under the commanded efforts `tau_cmd` (held over the step).
    /// The energy is not computed at every step (see [`energy_guard`]); [`energy`](Self::energy)
    /// gives it at any state.
    pub fn step(
        &mut self,
        model: &Model,
        state: &mut State,
        tau_cmd: &[f64],
    ) -> Result<(), SimError> {
        // A simulator made for another model: refused before any buffer is indexed.
        self.eval
            .ws
            .check(model)
            .map_err(|source| SimError::Dynamics { t: state.t, source })?;
        if self.guard.needs_initial() {
            let (kinetic, potential) = self.kinetic_and_potential(model, state)?;
            self.guard.start(kinetic, potential);
        }
        self.eval.method = self.config.method;
        self.eval.on = self.config.passive;
        let substeps = self.config.substeps.max(1);
        let h = self.config.dt / substeps as f64;
        for _ in 0..substeps {
            let power: f64 = tau_cmd
                .iter()
                .zip(&state.v)
                .map(|(t, v)| (t * v).abs())
                .sum();
            integrator::advance(
                self.config.integrator,
                &mut self.eval,
                &mut self.scratch,
                model,
                state,
                tau_cmd,
                h,
            )
            .map_err(|source| SimError::Dynamics { t: state.t, source })?;
            state.t += h;
            let check_energy = self.guard.advance(power, h);
            if !(all_finite(&state.q) && all_finite(&state.v)) {
                return Err(non_finite(model, state));
            }
            if check_energy {
                let (kinetic, potential) = self.kinetic_and_potential(model, state)?;
                self.guard.check(state.t, kinetic, potential)?;
            }
        }
        Ok(())
    }
}

/// The error for a state that is no longer finite, naming its first non-finite coordinate
/// (a position before a velocity).
#[cold]
fn non_finite(model: &Model, state: &State) -> SimError {
    let coordinate = match state.q.iter().position(|x| !x.is_finite()) {
        Some(i) => model
            .joint_of_q(i)
            .map_or(format!("q[{i}]"), |(n, _)| n.to_string()),
        None => {
            let i = state.v.iter().position(|x| !x.is_finite()).unwrap_or(0);
            model.v_name(i)
        }
    };
    SimError::NonFinite {
        t: state.t,
        coordinate,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::{pendulum_urdf, PARTICLE_URDF};
    use crate::urdf::model_from_str;
    use crate::ModelOptions;

    /// A state that stops being finite is named by its first non-finite coordinate, a position
    /// before a velocity; a step into it stops with that error.
    #[test]
    fn a_non_finite_state_names_its_coordinate() {
        let model = model_from_str(&pendulum_urdf(3, 1.0, 1.0), &ModelOptions::default()).unwrap();
        let name = |q: [f64; 3], v: [f64; 3]| {
            let state = State {
                t: 0.5,
                q: q.to_vec(),
                v: v.to_vec(),
            };
            match non_finite(&model, &state) {
                SimError::NonFinite { t, coordinate } => (t, coordinate),
                other => panic!("{other:?}"),
            }
        };
        let (inf, nan) = (f64::INFINITY, f64::NAN);
        assert_eq!(name([0.0, nan, 0.0], [inf; 3]), (0.5, "joint2".to_string()));
        assert_eq!(
            name([0.0; 3], [0.0, 0.0, -inf]),
            (0.5, "joint3".to_string())
        );
        // A point mass on two slides (no velocity product at all): the energy budget starts
        // at rest, then a step from the largest position and rate along x carries it past
        // f64::MAX.
        let model = model_from_str(PARTICLE_URDF, &ModelOptions::default()).unwrap();
        let mut sim = Simulator::new(&model, SimConfig::default()).unwrap();
        let mut state = State::at_rest(&model, vec![0.0; 2]);
        sim.step(&model, &mut state, &[0.0; 2]).unwrap();
        (state.q[0], state.v[0]) = (f64::MAX * 0.9999, 1e308);
        match sim.step(&model, &mut state, &[0.0; 2]) {
            Err(SimError::NonFinite { coordinate, .. }) => assert_eq!(coordinate, "x"),
            other => panic!("{other:?}"),
        }
    }
}
