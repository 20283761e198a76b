//! Analytical derivatives of inverse and forward dynamics against central differences of our
//! own `rnea` and forward dynamics along the tangent (`q ⊕ ε e_k` by `Model::integrate`), on
//! fixed, floating, mimic, planar, reduced and far-from-the-origin models; `H` from
//! `rnea_derivatives` against CRBA's, and `∂q̈/∂τ · H = 1`.
//!
//! Step and tolerance: the derivative along a direction is Richardson's five-point central
//! difference `(8 (f(h) − f(−h)) − (f(2h) − f(−2h))) / 12h`, off by the truncation
//! `h⁴ |f⁽⁵⁾| / 30` plus the rounding `1.5 ε_mach |f| / h`. With `|f|` of the order of `F`, the
//! largest `|f|` over the samples, and `h = 5e-4`, the rounding is `6.6e-13 F`; the truncation
//! is `2e-15 |f⁽⁵⁾|`, below the rounding for `|f⁽⁵⁾|` up to `300 F` (at `h = 1e-3` it was measured
//! at `2e-10 F` on the default arm's `∂q̈/∂q` and `6e-10 F` on the centimetre-sized mimic
//! gripper's, where a light link's `q̈` turns fast with `q`, and fell sixteenfold with `h/2`).
//! The tolerance is `TOL · (1 + F)` with `TOL = 1e-10`, a hundred times the rounding. Forward
//! dynamics solves with `H`, whose condition number `κ` (up to 5e4 here) multiplies the
//! rounding of `q̈` (`κ ε_mach |q̈|`, so `1.5 κ ε_mach F / h` in the difference): its tolerance
//! is `(TOL + 1.5 κ ε_mach / h) · (1 + F)`.

mod common;

use common::{pendulum_on_a_rail, random_q, Rng};
use spatial_dynamics_core::algorithms::kinematics::body_placements;
use spatial_dynamics_core::algorithms::{
    aba_derivatives, crba, forward_dynamics, rnea, rnea_derivatives, rnea_derivatives_with,
};
use spatial_dynamics_core::model::examples::{DEFAULT_ARM_URDF, MIMIC_GRIPPER_URDF};
use spatial_dynamics_core::spatial::{Force, Motion, Vector3};
use spatial_dynamics_core::{
    urdf, DynamicsError, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

const TREE: &str = include_str!("models/tree.urdf");

/// The central-difference step.
const H: f64 = 5e-4;
/// The relative tolerance of a five-point central difference (module doc).
const TOL: f64 = 1e-10;

fn load(text: &str, options: ModelOptions) -> Model {
    urdf::model_from_str(text, &options).unwrap()
}

fn floating(text: &str) -> Model {
    load(
        text,
        ModelOptions {
            floating_base: true,
            ..Default::default()
        },
    )
}

/// The tree with a floating joint in place of its planar base joint.
fn tree_with_a_floating_joint() -> Model {
    load(
        &TREE.replace(r#"type="planar""#, r#"type="floating""#),
        ModelOptions::default(),
    )
}

/// Every model the derivatives are checked on, by name.
fn models() -> Vec<(&'static str, Model)> {
    vec![
        (
            "default arm",
            load(DEFAULT_ARM_URDF, ModelOptions::default()),
        ),
        ("default arm, floating base", floating(DEFAULT_ARM_URDF)),
        (
            "mimic gripper",
            load(MIMIC_GRIPPER_URDF, ModelOptions::default()),
        ),
        (
            "tree (planar base joint)",
            load(TREE, ModelOptions::default()),
        ),
        ("tree, floating joint", tree_with_a_floating_joint()),
        (
            "default arm, planar fourth joint",
            load(
                &DEFAULT_ARM_URDF.replace(
                    r#"<joint name="joint4" type="revolute">"#,
                    r#"<joint name="joint4" type="planar">"#,
                ),
                ModelOptions::default(),
            ),
        ),
        (
            "default arm to link4, joint6 locked",
            load(
                DEFAULT_ARM_URDF,
                ModelOptions {
                    tips: vec!["link4".into()],
                    locked: vec![("joint6".into(), 0.8)],
                    ..Default::default()
                },
            ),
        ),
        (
            "tree from the torso",
            load(
                TREE,
                ModelOptions {
                    root: Some("torso".into()),
                    tips: vec!["left_hand".into(), "right_arm".into()],
                    ..Default::default()
                },
            ),
        ),
    ]
}

/// A state of `model`: `q`, and `v`, `a` (or `τ`) of about one.
struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
}

fn state(model: &Model, seed: u64) -> State {
    let mut rng = Rng::new(seed);
    State {
        q: random_q(model, &mut rng),
        v: rng.vector(model.nv(), 1.0),
        a: rng.vector(model.nv(), 1.0),
    }
}

/// `q ⊕ t e_k`.
fn along(model: &Model, q: &[f64], k: usize, t: f64) -> Vec<f64> {
    let mut e = vec![0.0; model.nv()];
    e[k] = 1.0;
    let mut out = q.to_vec();
    model.integrate(q, &e, t, &mut out).unwrap();
    out
}

/// `x + t e_k`.
fn moved(x: &[f64], k: usize, t: f64) -> Vec<f64> {
    let mut out = x.to_vec();
    out[k] += t;
    out
}

/// Column `k` of `∂f/∂x` by the five-point central difference (module doc), `f(t)` evaluating
/// at `x ⊕ t e_k`; and the largest `|f|` met.
fn central(f: &mut dyn FnMut(f64) -> Vec<f64>) -> (Vec<f64>, f64) {
    let [p2, p1, m1, m2] = [2.0 * H, H, -H, -2.0 * H].map(&mut *f);
    let scale = [&p2, &p1, &m1, &m2]
        .iter()
        .flat_map(|x| x.iter())
        .fold(0.0f64, |m, x| m.max(x.abs()));
    let column = (0..p1.len())
        .map(|i| (8.0 * (p1[i] - m1[i]) - (p2[i] - m2[i])) / (12.0 * H))
        .collect();
    (column, scale)
}

/// Fails unless column `k` of `analytic` matches `numeric` within `tol · (1 + scale)`.
fn assert_column(
    case: &str,
    what: &str,
    analytic: &nalgebra::DMatrix<f64>,
    k: usize,
    (numeric, scale): (Vec<f64>, f64),
    tol: f64,
) {
    for (i, &n) in numeric.iter().enumerate() {
        let err = (analytic[(i, k)] - n).abs();
        assert!(
            err <= tol * (1.0 + scale),
            "{case}: {what}[{i}][{k}] = {} against {n} by differences ({err:e}, scale {scale:e})",
            analytic[(i, k)]
        );
    }
}

fn check_rnea_derivatives(case: &str, model: &Model, s: &State, ext: &Externals<'_>) {
    let mut ws = Workspace::new(model);
    let d = rnea_derivatives_with(model, &mut ws, &s.q, &s.v, &s.a, ext).unwrap();
    let (dq, dv, h) = (d.dtau_dq.clone(), d.dtau_dv.clone(), d.mass_matrix.clone());
    let tau = ws.tau().to_vec();
    let mut id = |q: &[f64], v: &[f64], a: &[f64]| {
        spatial_dynamics_core::algorithms::rnea_with(model, &mut ws, q, v, a, ext)
            .unwrap()
            .to_vec()
    };
    let tau_rnea = id(&s.q, &s.v, &s.a);
    for (t, r) in tau.iter().zip(&tau_rnea) {
        assert!(
            (t - r).abs() <= 1e-12 * (1.0 + r.abs()),
            "{case}: τ {t} against rnea's {r}"
        );
    }
    for k in 0..model.nv() {
        let col = central(&mut |t| id(&along(model, &s.q, k, t), &s.v, &s.a));
        assert_column(case, "dtau_dq", &dq, k, col, TOL);
        let col = central(&mut |t| id(&s.q, &moved(&s.v, k, t), &s.a));
        assert_column(case, "dtau_dv", &dv, k, col, TOL);
        let col = central(&mut |t| id(&s.q, &s.v, &moved(&s.a, k, t)));
        assert_column(case, "M", &h, k, col, TOL);
    }
}

fn check_aba_derivatives(case: &str, model: &Model, s: &State, ext: &Externals<'_>) {
    let mut ws = Workspace::new(model);
    let tau = s.a.clone();
    let d = aba_derivatives(model, &mut ws, &s.q, &s.v, &tau, ext).unwrap();
    let (dq, dv, minv) = (d.ddq_dq.clone(), d.ddq_dv.clone(), d.minv.clone());
    let eigenvalues = crba(model, &mut ws, &s.q).unwrap().symmetric_eigenvalues();
    let kappa = eigenvalues.max() / eigenvalues.min();
    let tol = TOL + 1.5 * kappa * f64::EPSILON / H;
    let mut fd = |q: &[f64], v: &[f64], tau: &[f64]| {
        forward_dynamics(model, &mut ws, q, v, tau, ForwardDynamicsMethod::Crba, ext)
            .unwrap()
            .to_vec()
    };
    for k in 0..model.nv() {
        let col = central(&mut |t| fd(&along(model, &s.q, k, t), &s.v, &tau));
        assert_column(case, "ddq_dq", &dq, k, col, tol);
        let col = central(&mut |t| fd(&s.q, &moved(&s.v, k, t), &tau));
        assert_column(case, "ddq_dv", &dv, k, col, tol);
        let col = central(&mut |t| fd(&s.q, &s.v, &moved(&tau, k, t)));
        assert_column(case, "Minv", &minv, k, col, tol);
    }
}

#[test]
fn inverse_dynamics_derivatives_match_central_differences() {
    for (case, model) in models() {
        for seed in 1..4 {
            check_rnea_derivatives(case, &model, &state(&model, seed), &Externals::none());
        }
    }
}

/// One wrench on each body of `model` (body frame), components in ±2, seeded by `seed`.
fn random_wrenches(model: &Model, seed: u64) -> Vec<Force> {
    let mut rng = Rng::new(seed);
    (0..model.nbodies())
        .map(|_| {
            let w = rng.vector(6, 2.0);
            Force::new(
                Vector3::new(w[0], w[1], w[2]),
                Vector3::new(w[3], w[4], w[5]),
            )
        })
        .collect()
}

#[test]
fn inverse_dynamics_derivatives_with_external_wrenches_and_a_moving_base() {
    for (case, model) in models() {
        let wrenches = random_wrenches(&model, 7);
        let ext = Externals {
            wrenches: Some(&wrenches),
            root_velocity: Motion::new(Vector3::new(0.3, -0.2, 0.1), Vector3::new(0.5, 0.4, -0.6)),
            root_acceleration: Motion::new(
                Vector3::new(-0.1, 0.2, 0.4),
                Vector3::new(1.0, -2.0, 0.5),
            ),
        };
        check_rnea_derivatives(case, &model, &state(&model, 11), &ext);
    }
}

#[test]
fn forward_dynamics_derivatives_match_central_differences() {
    for (case, model) in models() {
        for seed in 1..3 {
            check_aba_derivatives(case, &model, &state(&model, seed), &Externals::none());
        }
    }
}

/// A free-floating root (the tree's floating joint; the default arm on a floating base) in a
/// world at rest, with wrenches fixed to the bodies and the world accelerating without turning,
/// takes the closed form of its pose columns of `∂q̈/∂q` and linear rate columns of `∂q̈/∂q̇`
/// (`aba_derivatives`' module doc): zero but, in the root's linear rows, `g_b × e_k` in
/// angular pose column `k` (`g_b = R_bᵀ (g − a_lin)`) and `e_k × ω` in linear rate column `k`.
/// They match central differences, as every other column does, and the general
/// `−H⁻¹ ∂τ/∂q`, `−H⁻¹ ∂τ/∂q̇` (from `rnea_derivatives_with` at `q̈`) to 1e-12 of `|g_b|` and
/// of `1 + |ω|`. With the world spinning (or, for the pose columns, turning) the closed form
/// would be wrong by about `|g|` or `|ω|`: the general path is taken and matches central
/// differences.
#[test]
fn a_free_floating_root_s_columns_are_in_closed_form_where_they_hold() {
    let models = [
        ("tree, floating joint", tree_with_a_floating_joint()),
        ("default arm, floating base", floating(DEFAULT_ARM_URDF)),
    ];
    for (case, model) in &models {
        let wrenches = random_wrenches(model, 13);
        let (zero, a_lin) = (Vector3::zeros(), Vector3::new(-0.4, 0.7, 1.3));
        let still = |a_lin| Externals {
            wrenches: Some(&wrenches),
            root_velocity: Motion::new(zero, zero),
            root_acceleration: Motion::new(zero, a_lin),
        };
        let spinning = Externals {
            root_velocity: Motion::new(Vector3::new(0.5, 0.4, -0.6), zero),
            ..still(zero)
        };
        let turning = Externals {
            root_acceleration: Motion::new(Vector3::new(1.0, -2.0, 0.5), a_lin),
            ..still(a_lin)
        };
        let s = state(model, 17);
        let nv = model.nv();
        let omega = Vector3::new(s.v[3], s.v[4], s.v[5]);
        // Whether the closed form holds for the pose columns, and for the rate columns.
        for (name, ext, pose_holds, rates_hold) in [
            ("wrenches", still(zero), true, true),
            ("wrenches, world accelerating", still(a_lin), true, true),
            ("world spinning", spinning, false, false),
            ("world turning", turning, false, true),
        ] {
            let case = format!("{case}, {name}");
            check_aba_derivatives(&case, model, &s, &ext);
            let mut ws = Workspace::new(model);
            let d = aba_derivatives(model, &mut ws, &s.q, &s.v, &s.a, &ext).unwrap();
            let (dq, dv, minv) = (d.ddq_dq.clone(), d.ddq_dv.clone(), d.minv.clone());
            let qdd = ws.qdd().to_vec();
            let id = rnea_derivatives_with(model, &mut ws, &s.q, &s.v, &qdd, &ext).unwrap();
            let (general_q, general_v) = (-&minv * id.dtau_dq, -&minv * id.dtau_dv);
            let e = body_placements(model, &mut ws, &s.q).unwrap()[0].rot;
            let g_b = e * (model.gravity() - ext.root_acceleration.lin);
            let (mut pose, mut rates) = (
                nalgebra::DMatrix::<f64>::zeros(nv, 6),
                nalgebra::DMatrix::<f64>::zeros(nv, 3),
            );
            for k in 0..3 {
                let e_k = Vector3::ith(k, 1.0);
                pose.view_mut((0, 3 + k), (3, 1))
                    .copy_from(&g_b.cross(&e_k));
                rates.view_mut((0, k), (3, 1)).copy_from(&e_k.cross(&omega));
            }
            for (what, got, general, closed_form, holds, scale) in [
                (
                    "ddq_dq",
                    dq.columns(0, 6),
                    general_q.columns(0, 6),
                    pose,
                    pose_holds,
                    g_b.norm(),
                ),
                (
                    "ddq_dv",
                    dv.columns(0, 3),
                    general_v.columns(0, 3),
                    rates,
                    rates_hold,
                    1.0 + omega.norm(),
                ),
            ] {
                let from_general = (got - general).amax();
                let from_closed = (got - closed_form).amax();
                assert!(
                    from_general <= 1e-12 * scale,
                    "{case}: {what} {from_general:e} from the general product"
                );
                if holds {
                    assert!(
                        from_closed <= 1e-12 * scale,
                        "{case}: {what} {from_closed:e}"
                    );
                } else if what == "ddq_dq" || name == "world spinning" {
                    assert!(
                        from_closed > 0.1,
                        "{case}: {what}: the closed form holds ({from_closed:e})"
                    );
                }
            }
        }
    }
}

#[test]
fn the_mass_matrix_is_crba_s_and_minv_inverts_it() {
    for (case, model) in models() {
        let s = state(&model, 5);
        let mut ws = Workspace::new(&model);
        let h = rnea_derivatives(&model, &mut ws, &s.q, &s.v, &s.a)
            .unwrap()
            .mass_matrix
            .clone();
        let h_crba = crba(&model, &mut ws, &s.q).unwrap().clone();
        let err = (&h - &h_crba).amax();
        assert!(
            err <= 1e-13 * (1.0 + h_crba.amax()),
            "{case}: H against CRBA's: {err:e}"
        );
        let minv = aba_derivatives(&model, &mut ws, &s.q, &s.v, &s.a, &Externals::none())
            .unwrap()
            .minv
            .clone();
        let identity = nalgebra::DMatrix::<f64>::identity(model.nv(), model.nv());
        // H⁻¹ H = 1 to the conditioning of H times the rounding of the solves.
        let err = (&minv * &h - &identity).amax();
        assert!(err <= 1e-10, "{case}: H⁻¹ H − 1 up to {err:e}");
    }
}

/// A workspace that has served other states and algorithms (forward dynamics by RNEA
/// columns, which writes `H` whole; both derivatives at another state) gives exactly the
/// derivatives a fresh one gives: sums restart from zero (mimic joints add entries up) and
/// nothing is left from before off the tree's pattern.
#[test]
fn a_used_workspace_gives_a_fresh_one_s_derivatives() {
    for (case, model) in models() {
        let (s1, s2) = (state(&model, 21), state(&model, 22));
        let mut used = Workspace::new(&model);
        let none = Externals::none();
        forward_dynamics(
            &model,
            &mut used,
            &s1.q,
            &s1.v,
            &s1.a,
            ForwardDynamicsMethod::RneaColumns,
            &none,
        )
        .unwrap();
        rnea_derivatives(&model, &mut used, &s1.q, &s1.v, &s1.a).unwrap();
        aba_derivatives(&model, &mut used, &s1.q, &s1.v, &s1.a, &none).unwrap();
        rnea_derivatives(&model, &mut used, &s1.q, &s1.v, &s1.a).unwrap();
        let mut fresh = Workspace::new(&model);
        let d = rnea_derivatives(&model, &mut used, &s2.q, &s2.v, &s2.a).unwrap();
        let (dq, dv, h) = (d.dtau_dq.clone(), d.dtau_dv.clone(), d.mass_matrix.clone());
        let tau = used.tau().to_vec();
        let f = rnea_derivatives(&model, &mut fresh, &s2.q, &s2.v, &s2.a).unwrap();
        assert_eq!(
            (&dq, &dv, &h),
            (f.dtau_dq, f.dtau_dv, f.mass_matrix),
            "{case}"
        );
        assert_eq!(tau, fresh.tau(), "{case}: τ");
        let d = aba_derivatives(&model, &mut used, &s2.q, &s2.v, &s2.a, &none).unwrap();
        let (dq, dv, minv) = (d.ddq_dq.clone(), d.ddq_dv.clone(), d.minv.clone());
        let f = aba_derivatives(&model, &mut fresh, &s2.q, &s2.v, &s2.a, &none).unwrap();
        assert_eq!((&dq, &dv, &minv), (f.ddq_dq, f.ddq_dv, f.minv), "{case}");
    }
}

#[test]
fn derivatives_do_not_depend_on_how_far_a_rail_carries_the_robot() {
    let model = load(&pendulum_on_a_rail(8), ModelOptions::default());
    let s = state(&model, 4);
    let mut far = s.q.clone();
    far[1] += 1500.0;
    assert_same_derivatives_at(&model, &s, &far, "rail: moved 1.5 km");
}

/// `∂τ/∂q` and `∂τ/∂q̇` at `far` (the state `s` with its position moved) equal those at `s` to
/// 1e-12 relative: a translation above the moving joints changes none of the dynamics.
fn assert_same_derivatives_at(model: &Model, s: &State, far: &[f64], case: &str) {
    let mut ws = Workspace::new(model);
    let near_d = rnea_derivatives(model, &mut ws, &s.q, &s.v, &s.a).unwrap();
    let near = [near_d.dtau_dq.clone(), near_d.dtau_dv.clone()];
    let far_d = rnea_derivatives(model, &mut ws, far, &s.v, &s.a).unwrap();
    for (what, n, f) in [
        ("dtau_dq", &near[0], far_d.dtau_dq),
        ("dtau_dv", &near[1], far_d.dtau_dv),
    ] {
        let err = (n - f).amax();
        assert!(err <= 1e-12 * (1.0 + n.amax()), "{case}: {what}: {err:e}");
    }
}

/// A robot a kilometre from the world origin: its derivatives are those it has at the origin.
#[test]
fn derivatives_do_not_depend_on_where_the_robot_stands() {
    for (case, model) in [
        ("default arm, floating base", floating(DEFAULT_ARM_URDF)),
        ("tree, floating joint", tree_with_a_floating_joint()),
    ] {
        let s = state(&model, 3);
        let mut far = s.q.clone();
        for (x, d) in far.iter_mut().zip([1000.0, -700.0, 300.0]) {
            *x += d;
        }
        assert_same_derivatives_at(&model, &s, &far, &format!("{case}: moved 1 km"));
        check_rnea_derivatives(
            case,
            &model,
            &State {
                q: far,
                v: s.v.clone(),
                a: s.a.clone(),
            },
            &Externals::none(),
        );
    }
}

/// Bad input gives the errors of `rnea` (inverse dynamics) and of forward dynamics.
#[test]
fn bad_input_gives_the_dynamics_errors() {
    let model = floating(DEFAULT_ARM_URDF);
    let s = state(&model, 1);
    let mut ws = Workspace::new(&model);
    let mut nan_v = s.v.clone();
    nan_v[3] = f64::NAN;
    let mut zero_quaternion = s.q.clone();
    zero_quaternion[3..7].fill(0.0);
    let none = Externals::none();
    for (q, v, a) in [
        (&s.q[..], &nan_v[..], &s.a[..]),
        (&zero_quaternion[..], &s.v[..], &s.a[..]),
        (&s.q[..], &s.v[..], &s.a[1..]),
        (&s.q[..2], &s.v[..], &s.a[..]),
    ] {
        let expected: DynamicsError = rnea(&model, &mut ws, q, v, a).unwrap_err();
        let got = rnea_derivatives(&model, &mut ws, q, v, a).unwrap_err();
        assert_eq!(got.to_string(), expected.to_string());
        let expected =
            forward_dynamics(&model, &mut ws, q, v, a, ForwardDynamicsMethod::Crba, &none)
                .unwrap_err();
        let got = aba_derivatives(&model, &mut ws, q, v, a, &none).unwrap_err();
        assert_eq!(got.to_string(), expected.to_string());
    }
}
