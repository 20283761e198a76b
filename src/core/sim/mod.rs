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
use integrator::StepError;
pub use servo::{CommandInterface, Servo, ServoAxis};

use crate::algorithms::energy::AbaEnergy;
use crate::algorithms::forward_dynamics::forward_dynamics_on_checked_shapes;
use crate::algorithms::validate::{all_finite, check_q, check_q_of, check_v};
use crate::algorithms::{energy, forward_dynamics};
use crate::error::{check_len, DynamicsError};
use crate::model::JointKind;
use crate::{Externals, ForwardDynamicsMethod, InstructionSet, Model, Workspace};
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
    /// The energy grew beyond what the initial energy and the work of the commands allow;
    /// `stalled`, a coordinate whose position the step could not move, when one is why.
    EnergyBlowUp {
        t: f64,
        energy: f64,
        bound: f64,
        stalled: Option<Stalled>,
    },
    /// Implicit Euler's Newton iterations did not converge on the step from time `t`, even
    /// halved `MAX_HALVINGS` times (`residual`: relative, at the last iterate of the last try).
    NotConverged { t: f64, residual: f64 },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Dynamics { t, source } => write!(f, "at t = {t:.6} s: {source}"),
            SimError::NonFinite { t, coordinate } => write!(f, "at t = {t:.6} s: the state of '{coordinate}' is no longer finite"),
            SimError::NotConverged { t, residual } => write!(
                f,
                "at t = {t:.6} s: implicit Euler's Newton iterations did not converge on this step even halved {} times (relative residual {residual:.1e} after at most {} iterations): take a smaller step",
                integrator::MAX_HALVINGS,
                integrator::MAX_NEWTON_ITERATIONS
            ),
            SimError::EnergyBlowUp { t, energy, bound, stalled } => {
                write!(
                    f,
                    "at t = {t:.6} s: the energy rose to {energy:.6e} J, above {bound:.6e} J (the initial energy plus the work of the commands plus a tolerance): the integrator is creating energy"
                )?;
                match stalled {
                    Some(Stalled { coordinate, position, spacing }) => write!(
                        f,
                        "; '{coordinate}' is at {position:e}, where the spacing of floating-point numbers ({spacing:e}) is more than a step moves it, so its position cannot follow its velocity: start it nearer zero (an angle of a continuous joint modulo 2π)"
                    ),
                    None => Ok(()),
                }
            }
        }
    }
}

impl std::error::Error for SimError {}

/// A coordinate whose position a step cannot move: at `position` the spacing of adjacent
/// floating-point numbers, `spacing`, is more than its velocity times the step, so `q + v h`
/// rounds back to `q` while the velocity changes, and the energy no longer balances.
#[derive(Clone, Debug, PartialEq)]
pub struct Stalled {
    pub coordinate: String,
    pub position: f64,
    pub spacing: f64,
}

impl Stalled {
    /// Among the coordinates whose velocity is their position's rate (revolute, continuous,
    /// prismatic and planar joints), the one furthest from zero that is moving but that a step of
    /// `h` cannot move, if any.
    fn find(model: &Model, state: &State, h: f64) -> Option<Stalled> {
        let euclidean = model.coordinate_joints().filter(|j| j.nq == j.nv);
        let coordinates =
            euclidean.flat_map(|j| (0..j.nv).map(move |k| (j.q_index + k, j.v_index + k)));
        coordinates
            .filter_map(|(iq, iv)| {
                let (q, v) = (state.q[iq], state.v[iv]);
                // The next float above |q| (q is finite here), less |q|.
                let spacing = f64::from_bits(q.abs().to_bits() + 1) - q.abs();
                (v != 0.0 && spacing > (v * h).abs()).then_some((iv, q, spacing))
            })
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map(|(iv, position, spacing)| Stalled {
                coordinate: model.v_name(iv),
                position,
                spacing,
            })
    }
}

/// Forward dynamics with the passive forces added: `a(q, v) = FD(q, v, clamp(τ_cmd) + τ_passive)`.
pub(crate) struct Evaluator {
    ws: Workspace,
    passive: PassiveForces,
    tau: Vec<f64>,
    method: ForwardDynamicsMethod,
    on: Passive,
    contacts: Option<Contacts>,
    /// The model has mimic joints, which ABA refuses (after its input checks).
    mimic: bool,
    /// Effort evaluations clamped to their limits.
    clamped: u64,
}

impl Evaluator {
    /// `q̈` at `(q, v)` under `tau_cmd`, into `out`. The shapes are the step's to establish
    /// ([`Simulator::step`] checks the state and the commands' length; the stages and passive
    /// efforts are the model's sizes, their quaternions normalised): forward dynamics tests
    /// only the values' finiteness and its result.
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
        let a = if self.mimic && self.method == ForwardDynamicsMethod::Aba {
            forward_dynamics(model, &mut self.ws, q, v, tau, self.method, &ext)?
        } else {
            forward_dynamics_on_checked_shapes(model, &mut self.ws, q, v, tau, self.method, &ext)?
        };
        out.copy_from_slice(a);
        Ok(())
    }

    /// The latest [`acceleration`](Self::acceleration) was at a state of the trajectory (a
    /// step's start, or implicit Euler's solved end), not a trial one: its contact penetration
    /// counts towards [`Simulator::max_penetration`].
    pub(crate) fn at_trajectory_state(&mut self) {
        if let Some(c) = &mut self.contacts {
            c.keep_penetration();
        }
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
    /// Implicit Euler: how many steps (or halves of steps) were halved so far.
    halved: u64,
}

/// A simulator for one model and configuration; [`step`](Self::step) allocates nothing.
pub struct Simulator {
    pub config: SimConfig,
    eval: Evaluator,
    scratch: Scratch,
    guard: EnergyGuard,
    /// The energy from ABA's workspace, for the guard.
    aba_energy: AbaEnergy,
    /// The bodies of the floating joints with coordinates of their own (quaternions to check).
    floating: Vec<usize>,
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
                mimic: model.has_mimic(),
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
                halved: 0,
            },
            config,
            guard: EnergyGuard::default(),
            aba_energy: AbaEnergy::new(model),
            floating: (0..model.nbodies())
                .filter(|&i| {
                    let joint = &model.bodies[i].joint;
                    joint.kind == JointKind::Floating && !joint.is_mimic()
                })
                .collect(),
        })
    }

    /// The state was set from outside (a reset): the energy budget of the divergence check
    /// starts again from the state of the next step.
    pub fn restart_energy_budget(&mut self) {
        self.guard.restart();
    }

    /// Deepest ground penetration of any contact point so far (m), over the states of the
    /// trajectory the simulator evaluated: every step's start (implicit Euler: every step's
    /// end), not the trial states within a step (Runge–Kutta stages, Newton iterates).
    pub fn max_penetration(&self) -> f64 {
        self.eval
            .contacts
            .as_ref()
            .map_or(0.0, |c| c.max_penetration)
    }

    /// Runs the dispatched passes in `set` ([`Workspace::set_instruction_set`]).
    pub fn set_instruction_set(&mut self, set: InstructionSet) {
        self.eval.ws.set_instruction_set(set);
    }

    /// How many times implicit Euler halved a step (or a half step) whose Newton iterations
    /// did not converge, so far ([`Integrator::ImplicitEuler`]).
    pub fn halved_steps(&self) -> u64 {
        self.scratch.halved
    }

    /// The commanded efforts `tau_cmd` as the dynamics receive them: clamped to their URDF limits
    /// when the passive forces include effort limits ([`Passive::effort_limits`]), else as they
    /// are; into `out` (`nv`).
    pub fn applied_effort(&self, tau_cmd: &[f64], out: &mut [f64]) {
        self.eval
            .passive
            .clamp_efforts(&self.config.passive, tau_cmd, out);
    }

    /// The passive joint forces the step applies: their joint data and which of them act
    /// ([`SimConfig::passive`]), as
    /// [`linearize_with_passive`](crate::algorithms::linearize_with_passive) takes them.
    pub fn passive_forces(&self) -> (&PassiveForces, &Passive) {
        (&self.eval.passive, &self.config.passive)
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
        self.check_shapes(model, state, tau_cmd)
            .map_err(|source| SimError::Dynamics { t: state.t, source })?;
        self.eval.method = self.config.method;
        self.eval.on = self.config.passive;
        let substeps = self.config.substeps.max(1);
        let h = self.config.dt / substeps as f64;
        // The guard counts the work of the efforts the dynamics receive (clamped to the limits).
        let limits = self.config.passive.effort_limits;
        let power_at =
            |passive: &PassiveForces, v: &[f64]| passive.commanded_power(limits, tau_cmd, v);
        for _ in 0..substeps {
            let power = power_at(&self.eval.passive, &state.v);
            let integrator = self.config.integrator;
            let evaluated = integrator::first_evaluation(
                integrator,
                &mut self.eval,
                &mut self.scratch,
                model,
                state,
                tau_cmd,
            );
            if matches!(evaluated, Ok(true)) {
                self.eval.at_trajectory_state();
            }
            if self.guard.due() {
                let evaluated = matches!(evaluated, Ok(true));
                let (kinetic, potential) = self.energy_at_start(model, state, evaluated)?;
                let mut checked = self.guard.record(state.t, kinetic, potential);
                if let Err(SimError::EnergyBlowUp { stalled, .. }) = &mut checked {
                    *stalled = Stalled::find(model, state, h);
                }
                checked?;
            }
            let t = state.t;
            evaluated
                .map_err(StepError::Dynamics)
                .and_then(|_| {
                    integrator::advance(
                        integrator,
                        &mut self.eval,
                        &mut self.scratch,
                        model,
                        state,
                        tau_cmd,
                        h,
                    )
                })
                .map_err(|e| match e {
                    StepError::Dynamics(source) => SimError::Dynamics { t, source },
                    StepError::NotConverged { residual } => SimError::NotConverged { t, residual },
                })?;
            state.t += h;
            // The larger of the powers at the sub-step's two ends: a command accelerating a
            // joint from rest does work the power at the start alone (zero) would not count.
            self.guard
                .advance(power.max(power_at(&self.eval.passive, &state.v)), h);
            if !(all_finite(&state.q) && all_finite(&state.v)) {
                return Err(non_finite(model, state));
            }
        }
        Ok(())
    }

    /// `(T, V)` at the state a sub-step starts from, for the energy guard: from what forward
    /// dynamics by ABA left in the workspace when the sub-step's first evaluation ran at that
    /// state (`evaluated`, [`AbaEnergy`]), else (the `crba` or `rnea_columns` method, a mimic
    /// model, implicit Euler, an evaluation that failed, a sum that overflowed) by a kinematics
    /// pass of its own, which checks the state and names what fails.
    fn energy_at_start(
        &mut self,
        model: &Model,
        state: &State,
        evaluated: bool,
    ) -> Result<(f64, f64), SimError> {
        let from_aba =
            evaluated && self.eval.method == ForwardDynamicsMethod::Aba && !self.eval.mimic;
        if from_aba {
            if let Some(energy) = self.aba_energy.of(model, &self.eval.ws) {
                return Ok(energy);
            }
        }
        self.kinetic_and_potential(model, state)
    }
}

impl Simulator {
    /// What forward dynamics leaves to the step ([`Evaluator::acceleration`]): the workspace
    /// is this model's, the state and the commands have its sizes, every floating joint's
    /// quaternion is not (near) zero. A failure is named by forward dynamics' own checks, in
    /// their order (a non-finite coordinate before a zero quaternion, `q` before `v` before
    /// `τ`), before any buffer is indexed.
    fn check_shapes(
        &self,
        model: &Model,
        state: &State,
        tau_cmd: &[f64],
    ) -> Result<(), DynamicsError> {
        let ws = &self.eval.ws;
        let sound = ws.check(model).is_ok()
            && state.q.len() == model.nq
            && state.v.len() == model.nv
            && tau_cmd.len() == model.nv
            && check_q_of(model, &state.q, &self.floating).is_ok();
        if sound {
            return Ok(());
        }
        check_q(model, ws, &state.q)?;
        check_v(model, "v", &state.v)?;
        check_len("tau", model.nv, tau_cmd.len())
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

    /// A step refuses bad inputs with the error forward dynamics gives them, whichever the
    /// integrator, method and passive forces: wrong sizes, non-finite values, a zero
    /// quaternion, two faults at once (the first in forward dynamics' order), and commands of
    /// the wrong size with passive forces on.
    #[test]
    fn a_step_refuses_what_forward_dynamics_refuses() {
        let options = ModelOptions {
            floating_base: true,
            ..Default::default()
        };
        let model = model_from_str(&pendulum_urdf(2, 1.0, 1.0), &options).unwrap();
        let (nq, nv) = (model.nq, model.nv);
        let good = |_: ()| (model.neutral(), vec![0.1; nv], vec![0.2; nv]);
        type Case = (Vec<f64>, Vec<f64>, Vec<f64>);
        let mut cases: Vec<Case> = Vec::new();
        let (nan, inf) = (f64::NAN, f64::INFINITY);
        for k in [0, 4, nq - 1] {
            let (mut q, v, t) = good(());
            q[k] = nan;
            cases.push((q, v, t));
        }
        let (mut q, v, t) = good(());
        q[3..7].fill(0.0);
        cases.push((q.clone(), v.clone(), t.clone()));
        let mut q_nan_too = q;
        q_nan_too[nq - 1] = inf;
        cases.push((q_nan_too, v, t));
        let (q, mut v, t) = good(());
        v[nv - 1] = inf;
        cases.push((q.clone(), v.clone(), t.clone()));
        cases.push((q.clone(), v, vec![0.0; nv + 1]));
        let (_, v, mut t) = good(());
        t[2] = nan;
        cases.push((q.clone(), v.clone(), t.clone()));
        cases.push((q[1..].to_vec(), v.clone(), t.clone()));
        cases.push((q.clone(), v[1..].to_vec(), t.clone()));
        cases.push((q, v, vec![0.0; nv - 1]));
        for integrator in Integrator::ALL {
            for method in ForwardDynamicsMethod::ALL {
                for passive in [Passive::default(), Passive::all()] {
                    let config = SimConfig {
                        integrator,
                        method,
                        passive,
                        ..Default::default()
                    };
                    let mut sim = Simulator::new(&model, config).unwrap();
                    let mut ws = Workspace::new(&model);
                    for (q, v, tau) in &cases {
                        // With effort limits on, a non-finite command is clamped, not refused.
                        if passive == Passive::all() && tau.len() == nv {
                            continue;
                        }
                        let expected = forward_dynamics(
                            &model,
                            &mut ws,
                            q,
                            v,
                            tau,
                            method,
                            &Externals::default(),
                        )
                        .map(|_| ())
                        .unwrap_err();
                        let mut state = State {
                            t: 0.25,
                            q: q.clone(),
                            v: v.clone(),
                        };
                        match sim.step(&model, &mut state, tau) {
                            Err(SimError::Dynamics { t, source }) => {
                                // Compared as text: a NaN value is not equal to itself.
                                assert_eq!(t, 0.25);
                                assert_eq!(
                                    format!("{source:?}"),
                                    format!("{expected:?}"),
                                    "{integrator} {method} {passive:?}"
                                )
                            }
                            other => panic!("{integrator} {method} {passive:?}: {other:?}"),
                        }
                    }
                }
            }
        }
    }
}
