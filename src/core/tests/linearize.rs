//! `linearize` and `integrate_jacobians` against independent references: the closed form of a
//! rod pendulum (continuous and discrete), central differences of one actual step of the
//! library's `Simulator` (semi-implicit Euler, passive forces off) on fixed, floating and mimic
//! models, and with every passive force on (and of its acceleration for `dt = 0`) on a chain
//! at its limits, and central differences of `Model::integrate` for the SE(3) Jacobians.
//!
//! Differences are measured on the tangent: `q ⊕ ε e_k` perturbs, and the answer's change is
//! `log(q⁺₀⁻¹ q⁺)`, computed here from the rotation's axis-angle and `V(φ)⁻¹` (an inverse by LU,
//! independent of the library's series and closed forms). Each derivative is Richardson's
//! five-point central difference `(8 (f(ε) − f(−ε)) − (f(2ε) − f(−2ε))) / 12ε`: truncation
//! `ε⁴ |f⁽⁵⁾| / 30`, rounding `1.5 ε_mach |f| / ε`. With `ε = 1e-4` and `|f|` (the state after a
//! step) of order `F`, the rounding is `3.3e-12 F`; the step solves with `H` (condition number
//! `κ` up to about 1e4 on these models), which scales the rounding of `q̇⁺ = q̇ + h q̈` by `h κ`.
//! The bound used is `TOL · (1 + F)` with `TOL = 1e-8`, over a hundred times that rounding; the
//! errors measured are printed (`--nocapture`): at most 3e-11 (1 + F) here.

mod common;

use common::{max_diff, random_q, Rng};
use nalgebra::{DMatrix, Matrix3, UnitQuaternion, Vector3};
use spatial_dynamics_core::algorithms::{
    aba_derivatives, forward_dynamics, integrate_jacobians, linearize, linearize_with_passive,
    Linearization,
};
use spatial_dynamics_core::model::examples::{pendulum_urdf, DEFAULT_ARM_URDF, MIMIC_GRIPPER_URDF};
use spatial_dynamics_core::model::JointKind;
use spatial_dynamics_core::sim::{Integrator, Passive, PassiveForces, SimConfig, Simulator, State};
use spatial_dynamics_core::{
    urdf, DynamicsError, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

const EPS: f64 = 1e-4;
const TOL: f64 = 1e-8;

fn load(text: &str, floating_base: bool) -> Model {
    let options = ModelOptions {
        floating_base,
        ..Default::default()
    };
    urdf::model_from_str(text, &options).unwrap()
}

/// Models of every kind of coordinate the step moves: revolute, floating (SE(3) exponential),
/// mimic followers (moving with their leader), planar.
fn models() -> Vec<(&'static str, Model)> {
    vec![
        ("default arm", load(DEFAULT_ARM_URDF, false)),
        ("default arm, floating base", load(DEFAULT_ARM_URDF, true)),
        ("mimic gripper", load(MIMIC_GRIPPER_URDF, false)),
        (
            "default arm, planar fourth joint",
            load(
                &DEFAULT_ARM_URDF.replace(
                    r#"<joint name="joint4" type="revolute">"#,
                    r#"<joint name="joint4" type="planar">"#,
                ),
                false,
            ),
        ),
    ]
}

/// `log(q0⁻¹ q1)` on the tangent: `q1 − q0` but for floating joints, whose six coordinates are
/// the twist `[ρ; φ]` with `exp([ρ; φ]) = M0⁻¹ M1`.
fn difference(model: &Model, q0: &[f64], q1: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; model.nv()];
    for j in model.coordinate_joints() {
        let (qi, vi) = (j.q_index, j.v_index);
        if *j.kind == JointKind::Floating {
            let pose = |q: &[f64]| {
                let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                    q[qi + 6],
                    q[qi + 3],
                    q[qi + 4],
                    q[qi + 5],
                ));
                (r, Vector3::new(q[qi], q[qi + 1], q[qi + 2]))
            };
            let ((r0, p0), (r1, p1)) = (pose(q0), pose(q1));
            let rel = r0.inverse() * r1;
            let phi = rel.scaled_axis();
            let p = r0.inverse() * (p1 - p0);
            let (t, w) = (phi.norm(), skew(&phi));
            let v = if t < 1e-8 {
                Matrix3::identity() + w * 0.5 + w * w / 6.0
            } else {
                Matrix3::identity()
                    + w * ((1.0 - t.cos()) / (t * t))
                    + w * w * ((t - t.sin()) / (t * t * t))
            };
            let rho = v.lu().solve(&p).unwrap();
            out[vi..vi + 3].copy_from_slice(rho.as_slice());
            out[vi + 3..vi + 6].copy_from_slice(phi.as_slice());
        } else {
            for k in 0..j.nv {
                out[vi + k] = q1[qi + k] - q0[qi + k];
            }
        }
    }
    out
}

fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// Richardson's five-point derivative of `f` at 0 along a scalar, each value a vector.
fn five_point(f: impl FnMut(f64) -> Vec<f64>) -> Vec<f64> {
    five_point_by(EPS, f)
}

/// [`five_point`] with the step `eps`.
fn five_point_by(eps: f64, mut f: impl FnMut(f64) -> Vec<f64>) -> Vec<f64> {
    let (p1, m1, p2, m2) = (f(eps), f(-eps), f(2.0 * eps), f(-2.0 * eps));
    (0..p1.len())
        .map(|i| (8.0 * (p1[i] - m1[i]) - (p2[i] - m2[i])) / (12.0 * eps))
        .collect()
}

/// A point to linearise about: a random `q`, `q̇` and `τ` of about one (a floating base also
/// turning at about one rad/s).
fn point(model: &Model, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut rng = Rng::new(seed);
    let q = random_q(model, &mut rng);
    let v = rng.vector(model.nv(), 1.0);
    let tau = rng.vector(model.nv(), 1.0);
    (q, v, tau)
}

/// The simulator's semi-implicit Euler step of `h` from `(q, v)` under `τ`, passive forces off
/// (or those of [`Step::with_passive`]): `[log(q⁺₀⁻¹ q⁺); v⁺]` with `q⁺₀` the step's end from
/// the unperturbed point.
struct Step {
    model: Model,
    sim: Simulator,
    q_end: Vec<f64>,
}

impl Step {
    fn new(model: &Model, q: &[f64], v: &[f64], tau: &[f64], h: f64) -> Step {
        Step::with_passive(model, q, v, tau, h, Passive::default())
    }

    fn with_passive(
        model: &Model,
        q: &[f64],
        v: &[f64],
        tau: &[f64],
        h: f64,
        passive: Passive,
    ) -> Step {
        let config = SimConfig {
            integrator: Integrator::SemiImplicitEuler,
            // CRBA: ABA does not take mimic joints.
            method: ForwardDynamicsMethod::Crba,
            dt: h,
            substeps: 1,
            passive,
            ..Default::default()
        };
        let mut step = Step {
            model: model.clone(),
            sim: Simulator::new(model, config).unwrap(),
            q_end: q.to_vec(),
        };
        let mut state = step.raw(q, v, tau);
        step.q_end = std::mem::take(&mut state.q);
        step
    }

    fn raw(&mut self, q: &[f64], v: &[f64], tau: &[f64]) -> State {
        let mut state = State {
            t: 0.0,
            q: q.to_vec(),
            v: v.to_vec(),
        };
        self.sim.restart_energy_budget();
        self.sim.step(&self.model, &mut state, tau).unwrap();
        state
    }

    fn x(&mut self, q: &[f64], v: &[f64], tau: &[f64]) -> Vec<f64> {
        let state = self.raw(q, v, tau);
        let mut x = difference(&self.model, &self.q_end, &state.q);
        x.extend_from_slice(&state.v);
        x
    }
}

/// `q ⊕ ε e_k`.
fn moved(model: &Model, q: &[f64], k: usize, eps: f64) -> Vec<f64> {
    let mut e = vec![0.0; model.nv()];
    e[k] = eps;
    let mut out = vec![0.0; model.nq()];
    model.integrate(q, &e, 1.0, &mut out).unwrap();
    out
}

/// Five-point differences of `f(q, q̇, τ)` along coordinate `k` of each: `q` on the tangent
/// ([`moved`]), `q̇` and `τ` as they are.
fn state_columns(
    model: &Model,
    (q, v, tau): (&[f64], &[f64], &[f64]),
    k: usize,
    eps: f64,
    mut f: impl FnMut(&[f64], &[f64], &[f64]) -> Vec<f64>,
) -> [Vec<f64>; 3] {
    let bumped = |x: &[f64], e: f64| {
        let mut x = x.to_vec();
        x[k] += e;
        x
    };
    [
        five_point_by(eps, |e| f(&moved(model, q, k, e), v, tau)),
        five_point_by(eps, |e| f(q, &bumped(v, e), tau)),
        five_point_by(eps, |e| f(q, v, &bumped(tau, e))),
    ]
}

fn column(m: &DMatrix<f64>, c: usize) -> Vec<f64> {
    m.column(c).iter().copied().collect()
}

/// The discrete map's columns are the central differences of one simulator step with respect
/// to `q` (on the tangent), `q̇` and `τ`, at a 1 ms step and at a 50 ms one (where the SE(3)
/// Jacobians of a turning floating base are far from the identity).
#[test]
fn discrete_map_is_the_derivative_of_one_simulator_step() {
    for (name, model) in models() {
        let nv = model.nv();
        let mut ws = Workspace::new(&model);
        let mut lin = Linearization::new(&model);
        for (seed, h) in [(1, 1e-3), (2, 5e-2)] {
            let (q, v, tau) = point(&model, seed);
            linearize(&model, &mut ws, &q, &v, &tau, h, &mut lin).unwrap();
            let mut step = Step::new(&model, &q, &v, &tau, h);
            let scale = 1.0
                + step
                    .x(&q, &v, &tau)
                    .iter()
                    .fold(0.0f64, |m, x| m.max(x.abs()));
            let scale = scale.max(1.0 + q.iter().fold(0.0f64, |m, x| m.max(x.abs())));
            let mut worst = 0.0f64;
            for k in 0..nv {
                let dq = five_point(|e| step.x(&moved(&model, &q, k, e), &v, &tau));
                let dv = five_point(|e| {
                    let mut v = v.clone();
                    v[k] += e;
                    step.x(&q, &v, &tau)
                });
                let du = five_point(|e| {
                    let mut tau = tau.clone();
                    tau[k] += e;
                    step.x(&q, &v, &tau)
                });
                for (what, fd, analytic) in [
                    ("∂x⁺/∂q", dq, column(lin.a(), k)),
                    ("∂x⁺/∂q̇", dv, column(lin.a(), nv + k)),
                    ("∂x⁺/∂τ", du, column(lin.b(), k)),
                ] {
                    let err = max_diff(&fd, &analytic);
                    worst = worst.max(err / scale);
                    assert!(
                        err <= TOL * scale,
                        "{name}, h = {h}: {what} column {k} off by {err:e} (bound {:e})\nfd {fd:?}\nanalytic {analytic:?}",
                        TOL * scale
                    );
                }
            }
            println!("{name}, h = {h}: largest error {worst:.1e} × (1 + F)");
        }
    }
}

/// `D_q`, `D_v` of `q ⊕ v dt` against central differences of `Model::integrate`, for floating
/// steps whose rotation is below, near and well above the series' threshold (θ = 1e-3 … 2.5).
#[test]
fn integrate_jacobians_are_the_derivatives_of_integrate() {
    let model = load(DEFAULT_ARM_URDF, true);
    let nv = model.nv();
    let (mut dq, mut dv) = (DMatrix::zeros(nv, nv), DMatrix::zeros(nv, nv));
    for (seed, theta) in [(3, 1e-3), (4, 0.049), (5, 0.051), (6, 0.7), (7, 2.5)] {
        let mut rng = Rng::new(seed);
        let q = random_q(&model, &mut rng);
        let mut v = rng.vector(nv, 1.0);
        let w = Vector3::new(v[3], v[4], v[5]);
        let w = w * (theta / w.norm());
        v[3..6].copy_from_slice(w.as_slice());
        integrate_jacobians(&model, &q, &v, 1.0, &mut dq, &mut dv).unwrap();
        let mut end = vec![0.0; model.nq()];
        model.integrate(&q, &v, 1.0, &mut end).unwrap();
        let step = |q: &[f64], v: &[f64]| {
            let mut out = vec![0.0; model.nq()];
            model.integrate(q, v, 1.0, &mut out).unwrap();
            difference(&model, &end, &out)
        };
        for k in 0..nv {
            let fd_q = five_point(|e| step(&moved(&model, &q, k, e), &v));
            let fd_v = five_point(|e| {
                let mut v = v.clone();
                v[k] += e;
                step(&q, &v)
            });
            for (what, fd, analytic) in
                [("D_q", fd_q, column(&dq, k)), ("D_v", fd_v, column(&dv, k))]
            {
                let err = max_diff(&fd, &analytic);
                assert!(
                    err < 1e-9,
                    "θ = {theta}: {what} column {k} off by {err:e}\nfd {fd:?}\nanalytic {analytic:?}"
                );
            }
        }
    }
}

/// Non-finite `v` or `dt` are refused naming them; a huge turn (`|φ| = 1e200`) is finite (the
/// coefficients tend to zero) and a step whose angle overflows is refused naming the joint: no
/// NaN is ever returned.
#[test]
fn integrate_jacobians_refuse_what_is_not_finite() {
    let model = load(DEFAULT_ARM_URDF, true);
    let nv = model.nv();
    let (mut dq, mut dv) = (DMatrix::zeros(nv, nv), DMatrix::zeros(nv, nv));
    let q = model.neutral();
    let mut v = vec![0.0; nv];
    v[4] = f64::NAN;
    let e = integrate_jacobians(&model, &q, &v, 1.0, &mut dq, &mut dv).unwrap_err();
    assert!(e.to_string().contains("v[4]"), "{e}");
    v[4] = 1.0;
    let e = integrate_jacobians(&model, &q, &v, f64::INFINITY, &mut dq, &mut dv).unwrap_err();
    assert!(e.to_string().contains("dt is inf"), "{e}");
    for (turn, dt) in [(1e200, 1.0), (1.0, 1e160), (1e77, 1.0)] {
        v[5] = turn;
        let answer = integrate_jacobians(&model, &q, &v, dt, &mut dq, &mut dv);
        match answer {
            Ok(()) => assert!(
                dq.iter().chain(dv.iter()).all(|x| x.is_finite()),
                "|φ| = {turn}·{dt}: {dv}"
            ),
            Err(e) => assert!(e.to_string().contains("overflowed"), "{e}"),
        }
    }
    v[3] = 1e300;
    v[5] = 1e300;
    let e = integrate_jacobians(&model, &q, &v, 1.0, &mut dq, &mut dv).unwrap_err();
    assert!(e.to_string().contains("the step v·dt"), "{e}");
}

/// A rod pendulum (length `l`, mass `m`, about `y`, hanging along `−z`):
/// `q̈ = (τ − m g (l/2) sin q) / (m l²/3)`, so continuous `A = [0 1; −(3g/2l) cos q 0]`,
/// `B = [0; 3/(m l²)]`, and one semi-implicit Euler step of `h` (`q⁺ = q + h q̇⁺`) has
/// `A = [1 + h² a  h; h a  1]`, `B = [h² b; h b]` with `a = −(3g/2l) cos q`, `b = 3/(m l²)`.
#[test]
fn pendulum_matches_its_closed_form() {
    let (l, m) = (0.8, 1.7);
    let model = load(&pendulum_urdf(1, l, m), false);
    let g = -model.gravity().z;
    let mut ws = Workspace::new(&model);
    let mut lin = Linearization::new(&model);
    for (q, v, tau) in [(0.0, 0.0, 0.0), (0.9, -1.3, 0.4), (2.8, 3.0, -2.0)] {
        let (a, b) = (-1.5 * g / l * f64::cos(q), 3.0 / (m * l * l));
        linearize(&model, &mut ws, &[q], &[v], &[tau], 0.0, &mut lin).unwrap();
        let expected_a = [0.0, 1.0, a, 0.0];
        let got_a: Vec<f64> = lin.a().transpose().iter().copied().collect();
        assert!(
            max_diff(&got_a, &expected_a) < 1e-12,
            "continuous A at q = {q}: {got_a:?}"
        );
        assert!(
            max_diff(lin.b().as_slice(), &[0.0, b]) < 1e-12,
            "continuous B at q = {q}"
        );
        let h = 0.01;
        linearize(&model, &mut ws, &[q], &[v], &[tau], h, &mut lin).unwrap();
        let expected_a = [1.0 + h * h * a, h, h * a, 1.0];
        let got_a: Vec<f64> = lin.a().transpose().iter().copied().collect();
        assert!(
            max_diff(&got_a, &expected_a) < 1e-12,
            "discrete A at q = {q}: {got_a:?}"
        );
        assert!(
            max_diff(lin.b().as_slice(), &[h * h * b, h * b]) < 1e-12,
            "discrete B at q = {q}"
        );
    }
}

/// The continuous `A`, `B` are the first-order terms of the discrete ones, `(A_h − 1)/h → A`,
/// `B_h / h → B` (error `O(h)`), on a floating base with a turning twist (where `A`'s corner is
/// `−ad(ν)`); its lower rows are `aba_derivatives`.
#[test]
fn continuous_map_is_the_limit_of_the_discrete_one() {
    let model = load(DEFAULT_ARM_URDF, true);
    let nv = model.nv();
    let (q, v, tau) = point(&model, 8);
    let mut ws = Workspace::new(&model);
    let mut continuous = Linearization::new(&model);
    let mut discrete = Linearization::new(&model);
    linearize(&model, &mut ws, &q, &v, &tau, 0.0, &mut continuous).unwrap();
    let mut errors = Vec::new();
    for h in [1e-4, 5e-5] {
        linearize(&model, &mut ws, &q, &v, &tau, h, &mut discrete).unwrap();
        let rate_a = (discrete.a() - DMatrix::identity(2 * nv, 2 * nv)) / h;
        let rate_b = discrete.b() / h;
        let err = (rate_a - continuous.a())
            .amax()
            .max((rate_b - continuous.b()).amax());
        errors.push(err);
    }
    let scale = 1.0 + continuous.a().amax();
    assert!(
        errors[0] < 1e-2 * scale,
        "first-order terms differ by {:e}",
        errors[0]
    );
    // O(h): halving h halves the difference.
    assert!(
        (errors[0] / errors[1] - 2.0).abs() < 0.1,
        "not first order: {errors:?}"
    );
    let d = aba_derivatives(&model, &mut ws, &q, &v, &tau, &Externals::none()).unwrap();
    let lower = continuous.a().rows(nv, nv).clone_owned();
    assert_eq!(lower.columns(0, nv), *d.ddq_dq);
    assert_eq!(lower.columns(nv, nv), *d.ddq_dv);
    assert_eq!(continuous.b().rows(nv, nv).clone_owned(), *d.minv);
}

#[test]
fn a_negative_or_non_finite_step_and_bad_inputs_are_refused() {
    let model = load(DEFAULT_ARM_URDF, false);
    let mut ws = Workspace::new(&model);
    let mut lin = Linearization::new(&model);
    let (q, v, tau) = point(&model, 9);
    for dt in [-1e-3, f64::NAN, f64::INFINITY] {
        let err = linearize(&model, &mut ws, &q, &v, &tau, dt, &mut lin).unwrap_err();
        assert!(
            matches!(err, DynamicsError::BadStep { .. }),
            "dt = {dt}: {err}"
        );
        assert!(err.to_string().contains("dt is"), "{err}");
    }
    let mut bad = v.clone();
    bad[2] = f64::NAN;
    let err = linearize(&model, &mut ws, &q, &bad, &tau, 0.0, &mut lin).unwrap_err();
    assert!(
        matches!(
            err,
            DynamicsError::NonFinite {
                vector: "v",
                index: 2,
                ..
            }
        ),
        "{err}"
    );
    let err = linearize(&model, &mut ws, &q, &v, &tau[1..], 0.0, &mut lin).unwrap_err();
    assert!(
        matches!(err, DynamicsError::Length { vector: "tau", .. }),
        "{err}"
    );
    let other = load(MIMIC_GRIPPER_URDF, false);
    let mut other_lin = Linearization::new(&other);
    let err = linearize(&model, &mut ws, &q, &v, &tau, 0.0, &mut other_lin).unwrap_err();
    assert!(matches!(err, DynamicsError::Length { .. }), "{err}");
}

#[test]
fn linearize_allocates_nothing() {
    let model = load(DEFAULT_ARM_URDF, true);
    let mut ws = Workspace::new(&model);
    let mut lin = Linearization::new(&model);
    let (q, v, tau) = point(&model, 10);
    linearize(&model, &mut ws, &q, &v, &tau, 1e-3, &mut lin).unwrap();
    for dt in [0.0, 1e-3] {
        let n = common::allocations_during(|| {
            linearize(&model, &mut ws, &q, &v, &tau, dt, &mut lin).unwrap();
        });
        assert_eq!(n, 0, "dt = {dt}: {n} allocations");
    }
}

/// Three revolute joints about `y` in a chain, each with damping 0.3, friction 0.2, position
/// limits `[−1, 1]` and an effort limit of 5.
fn passive_chain() -> Model {
    let inertial = r#"<inertial><origin xyz="0 0 0.2"/><mass value="1"/><inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.005"/></inertial>"#;
    let mut urdf = String::from(r#"<robot name="passive_chain"><link name="world"/>"#);
    for i in 1..=3 {
        let parent = if i == 1 {
            "world".to_string()
        } else {
            format!("l{}", i - 1)
        };
        urdf += &format!(
            r#"<link name="l{i}">{inertial}</link>
            <joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>
            <origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
            <limit lower="-1" upper="1" effort="5" velocity="10"/>
            <dynamics damping="0.3" friction="0.2"/></joint>"#
        );
    }
    urdf += "</robot>";
    load(&urdf, false)
}

/// The points about which [`linearization_includes_the_simulators_passive_forces`] linearises,
/// `(q, q̇, τ)`: joint 1 outside its upper limit moving further out (spring and damper), then
/// outside its lower limit moving back in (spring alone); joint 2 inside its limits, slow enough
/// for the smoothed friction to curve (`q̇ = 2 v_s`); joint 3's command of 8 clamped to 5.
#[allow(clippy::type_complexity)]
fn passive_points() -> [(Vec<f64>, Vec<f64>, Vec<f64>); 2] {
    [
        (
            vec![1.2, 0.3, -0.5],
            vec![0.5, -0.02, 0.3],
            vec![1.0, -0.5, 8.0],
        ),
        (
            vec![-1.1, -0.4, 0.6],
            vec![0.4, 0.02, -0.7],
            vec![-1.0, 0.5, -8.0],
        ),
    ]
}

/// `A`, `B` of the simulator's dynamics with damping, friction, effort and position limits on:
/// for `dt = 1 ms` the central differences of one step of the simulator itself (semi-implicit
/// Euler with those passive forces), and for `dt = 0` the lower rows against central
/// differences of its acceleration `FD(q, q̇, clamp(τ) + τ_p)` ([`PassiveForces::total`], as
/// the simulator evaluates it), the upper rows `[0 1]`.
///
/// The step is `ε = 1e-6`: every kink (the bounds, the damper's switch at `q̇ = 0`, the effort
/// clamp) is more than `2ε` away, and the friction `tanh(q̇ / v_s)` with `v_s = 0.01` has
/// `|f⁽⁵⁾| ~ v_s⁻⁵ = 1e10`, a truncation `ε⁴ |f⁽⁵⁾| / 30 ≈ 3e-16`; rounding is
/// `1.5 ε_mach F / ε ≈ 3.3e-10 F` for values of order `F` (up to the limit spring's 1000 N·m/rad
/// over `H`), times the solve's conditioning. The bound is `1e-6 (1 + F)`; the errors measured
/// are printed (`--nocapture`): at most 4e-9 (1 + F).
#[test]
fn linearization_includes_the_simulators_passive_forces() {
    const EPS_PASSIVE: f64 = 1e-6;
    const TOL_PASSIVE: f64 = 1e-6;
    let model = passive_chain();
    let nv = model.nv();
    let forces = PassiveForces::new(&model);
    let on = Passive::all();
    let mut ws = Workspace::new(&model);
    let mut lin = Linearization::new(&model);
    let mut fd_ws = Workspace::new(&model);
    let mut total = vec![0.0; nv];
    let mut qdd = |q: &[f64], v: &[f64], tau: &[f64]| {
        forces.total(&on, q, v, tau, &mut total);
        let a = forward_dynamics(
            &model,
            &mut fd_ws,
            q,
            v,
            &total,
            ForwardDynamicsMethod::Aba,
            &Externals::none(),
        )
        .unwrap();
        a.to_vec()
    };
    let check = |what: &str, k: usize, fd: &[f64], analytic: &[f64], scale: f64| {
        let err = max_diff(fd, analytic);
        assert!(
            err <= TOL_PASSIVE * scale,
            "{what} column {k} off by {err:e}\nfd {fd:?}\nanalytic {analytic:?}"
        );
        err / scale
    };
    for (q, v, tau) in passive_points() {
        let mut worst = 0.0f64;
        // Continuous time: the lower rows are the derivatives of the simulator's q̈.
        linearize_with_passive(
            &model,
            &mut ws,
            &q,
            &v,
            &tau,
            0.0,
            Some((&forces, &on)),
            &mut lin,
        )
        .unwrap();
        let a0 = qdd(&q, &v, &tau);
        let scale = 1.0 + a0.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(
            max_diff(ws.qdd(), &a0) < 1e-12 * scale,
            "q̈ {:?} vs {a0:?}",
            ws.qdd()
        );
        for k in 0..nv {
            let lower = |m: &DMatrix<f64>, c: usize| column(m, c)[nv..].to_vec();
            let upper = |m: &DMatrix<f64>, c: usize| column(m, c)[..nv].to_vec();
            let [dq, dv, du] = state_columns(&model, (&q, &v, &tau), k, EPS_PASSIVE, &mut qdd);
            worst = worst.max(check("continuous ∂q̈/∂q", k, &dq, &lower(lin.a(), k), scale));
            worst = worst.max(check(
                "continuous ∂q̈/∂q̇",
                k,
                &dv,
                &lower(lin.a(), nv + k),
                scale,
            ));
            worst = worst.max(check("continuous ∂q̈/∂τ", k, &du, &lower(lin.b(), k), scale));
            let mut e = vec![0.0; nv];
            e[k] = 1.0;
            assert_eq!(upper(lin.a(), nv + k), e);
            assert!(upper(lin.a(), k)
                .iter()
                .chain(&upper(lin.b(), k))
                .all(|&x| x == 0.0));
        }
        // The clamped command moves nothing.
        assert!(column(lin.b(), 2).iter().all(|&x| x == 0.0));
        // Discrete time: the columns are the derivatives of the simulator's step.
        let h = 1e-3;
        linearize_with_passive(
            &model,
            &mut ws,
            &q,
            &v,
            &tau,
            h,
            Some((&forces, &on)),
            &mut lin,
        )
        .unwrap();
        let mut step = Step::with_passive(&model, &q, &v, &tau, h, on);
        let x0 = step.x(&q, &v, &tau);
        let scale = 1.0 + x0.iter().chain(&q).fold(0.0f64, |m, x| m.max(x.abs()));
        for k in 0..nv {
            let [dq, dv, du] =
                state_columns(&model, (&q, &v, &tau), k, EPS_PASSIVE, |q, v, tau| {
                    step.x(q, v, tau)
                });
            worst = worst.max(check("∂x⁺/∂q", k, &dq, &column(lin.a(), k), scale));
            worst = worst.max(check("∂x⁺/∂q̇", k, &dv, &column(lin.a(), nv + k), scale));
            worst = worst.max(check("∂x⁺/∂τ", k, &du, &column(lin.b(), k), scale));
        }
        println!("passive chain at q = {q:?}: largest error {worst:.1e} × (1 + F)");
    }
}

/// With passive forces the linearisation allocates nothing either.
#[test]
fn linearize_with_passive_allocates_nothing() {
    let model = passive_chain();
    let forces = PassiveForces::new(&model);
    let on = Passive::all();
    let mut ws = Workspace::new(&model);
    let mut lin = Linearization::new(&model);
    let (q, v, tau) = passive_points()[0].clone();
    let passive = Some((&forces, &on));
    linearize_with_passive(&model, &mut ws, &q, &v, &tau, 1e-3, passive, &mut lin).unwrap();
    for dt in [0.0, 1e-3] {
        let n = common::allocations_during(|| {
            linearize_with_passive(&model, &mut ws, &q, &v, &tau, dt, passive, &mut lin).unwrap();
        });
        assert_eq!(n, 0, "dt = {dt}: {n} allocations");
    }
}
