//! `rnea_rows` (RNEA on many states, blocks of them in the lanes of each instruction) against
//! the scalar `rnea` row by row: the same bits for every state, on models the lanes cover
//! (turns and slides along coordinate axes and other axes, placements with and without
//! rotation, mimic joints) and models they do not (planar and floating joints), with row counts
//! that leave a remainder; and the same error, at the same row, when one state of a block is
//! bad.

use spatial_dynamics_core::algorithms::lanes::{covers, LANES};
use spatial_dynamics_core::algorithms::{rnea, rnea_rows};
use spatial_dynamics_core::model::examples::{
    pendulum_urdf, DEFAULT_ARM_URDF, LAMP_URDF, MIMIC_GRIPPER_URDF, PARTICLE_URDF,
};
use spatial_dynamics_core::{urdf, DynamicsError, Model, ModelOptions, Workspace};

mod common;
use common::{random_q, Rng};

/// Each model, and whether the lanes cover it.
fn models() -> Vec<(Model, bool)> {
    let quarter_turns = include_str!("models/quarter_turns.urdf");
    let fixed = ModelOptions::default();
    let floating = ModelOptions {
        floating_base: true,
        ..ModelOptions::default()
    };
    let cases = [
        (DEFAULT_ARM_URDF.to_string(), &fixed, true),
        (MIMIC_GRIPPER_URDF.to_string(), &fixed, true),
        // A planar base: row by row.
        (LAMP_URDF.to_string(), &fixed, false),
        (pendulum_urdf(7, 0.5, 0.7), &fixed, true),
        (
            include_str!("models/turn_slide.urdf").to_string(),
            &fixed,
            true,
        ),
        // Turns and slides under rotated placements, a turn about another axis, slides at π/4.
        (quarter_turns.to_string(), &fixed, true),
        // A turn and a slide about and along an axis with three nonzero components.
        (
            quarter_turns
                .replace(
                    r#"<axis xyz="0.6 0.8 0"/>"#,
                    r#"<axis xyz="0.48 0.6 0.64"/>"#,
                )
                .replacen(
                    r#"<axis xyz="0 1 0"/>"#,
                    r#"<axis xyz="0.64 -0.48 0.6"/>"#,
                    2,
                ),
            &fixed,
            true,
        ),
        // Every joint along a coordinate axis.
        (
            quarter_turns
                .replace(r#"<axis xyz="0.6 0.8 0"/>"#, r#"<axis xyz="1 0 0"/>"#)
                .replace(r#"rpy="0 0 -0.7853981633974483""#, r#"rpy="0 0 0""#),
            &fixed,
            true,
        ),
        // Planar and floating joints: row by row.
        (include_str!("models/tree.urdf").to_string(), &fixed, false),
        (DEFAULT_ARM_URDF.to_string(), &floating, false),
        (PARTICLE_URDF.to_string(), &fixed, true),
    ];
    cases
        .into_iter()
        .map(|(text, options, covered)| (urdf::model_from_str(&text, options).unwrap(), covered))
        .collect()
}

/// `rows` random states of `model` (q, v, a row after row); every fifth row's coordinates
/// scaled far out, so that turn angles beyond the fast sine's range and large velocities occur.
fn states(model: &Model, rows: usize, rng: &mut Rng) -> [Vec<f64>; 3] {
    let (mut q, mut v, mut a) = (Vec::new(), Vec::new(), Vec::new());
    for r in 0..rows {
        let far = if r % 5 == 4 { 3.0e5 } else { 1.0 };
        let mut q_row = random_q(model, rng);
        if model.nq() == model.nv() {
            q_row.iter_mut().for_each(|x| *x *= far);
        }
        q.extend(q_row);
        v.extend(rng.vector(model.nv(), 3.0 * far.sqrt()));
        a.extend(rng.vector(model.nv(), 5.0));
    }
    [q, v, a]
}

/// `rnea` on row `r` of the rows.
fn scalar_row(
    model: &Model,
    ws: &mut Workspace,
    [q, v, a]: &[Vec<f64>; 3],
    r: usize,
) -> Result<Vec<f64>, DynamicsError> {
    let (nq, nv) = (model.nq(), model.nv());
    let q = &q[r * nq..(r + 1) * nq];
    let (v, a) = (&v[r * nv..(r + 1) * nv], &a[r * nv..(r + 1) * nv]);
    rnea(model, ws, q, v, a).map(<[f64]>::to_vec)
}

#[test]
fn every_row_has_the_bits_of_rnea() {
    let mut rng = Rng::new(28);
    let mut covered_bodies = 0;
    for (model, covered) in models() {
        assert_eq!(covers(&model), covered, "{}", model.name());
        if covered {
            covered_bodies += model.nbodies();
        }
        let mut ws = Workspace::new(&model);
        let mut scalar_ws = Workspace::new(&model);
        for rows in [0, 1, LANES, LANES + 1, 2 * LANES + 1, 7, 64 + 3] {
            let inputs = states(&model, rows, &mut rng);
            let mut tau = vec![f64::NAN; rows * model.nv()];
            let [q, v, a] = &inputs;
            rnea_rows(&model, &mut ws, q, v, a, &mut tau).unwrap();
            for r in 0..rows {
                let expected = scalar_row(&model, &mut scalar_ws, &inputs, r).unwrap();
                let got = &tau[r * model.nv()..(r + 1) * model.nv()];
                let bits = |x: &[f64]| x.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(got),
                    bits(&expected),
                    "{}, row {r} of {rows}: {got:?} against {expected:?}",
                    model.name()
                );
            }
        }
    }
    assert!(covered_bodies > 30, "{covered_bodies} bodies in lanes");
}

/// A bad value in lane `k` of a block (a non-finite input, or inputs whose `τ` overflows) gives
/// the scalar `rnea`'s error for that row, at that row; the rows before it are computed.
#[test]
fn a_bad_state_in_any_lane_gives_the_scalar_error_at_its_row() {
    let model = urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap();
    let (nq, nv) = (model.nq(), model.nv());
    let mut ws = Workspace::new(&model);
    let mut rng = Rng::new(5);
    let rows = 3 * LANES + 1;
    for bad_row in 0..rows {
        for (vector, value) in [
            (0, f64::NAN),
            (1, f64::INFINITY),
            (2, -f64::INFINITY),
            (1, 1e200),
        ] {
            let mut inputs = states(&model, rows, &mut rng);
            let width = [nq, nv, nv][vector];
            inputs[vector][bad_row * width + 2] = value;
            let expected = scalar_row(&model, &mut Workspace::new(&model), &inputs, bad_row)
                .expect_err("a bad state");
            if value == 1e200 {
                assert!(matches!(expected, DynamicsError::NonFiniteResult { .. }));
            }
            let mut tau = vec![0.0; rows * nv];
            let [q, v, a] = &inputs;
            let got = rnea_rows(&model, &mut ws, q, v, a, &mut tau);
            // Compared as text: a NaN value in the error is not equal to itself.
            let text = |e: Result<(), (usize, DynamicsError)>| format!("{e:?}");
            assert_eq!(text(got), text(Err((bad_row, expected))), "row {bad_row}");
            for r in 0..bad_row {
                let expected = scalar_row(&model, &mut Workspace::new(&model), &inputs, r);
                assert_eq!(
                    &tau[r * nv..(r + 1) * nv],
                    &expected.unwrap()[..],
                    "row {r}"
                );
            }
        }
    }
}

/// Rows of the wrong length and a workspace of another model are errors, not panics.
#[test]
fn wrong_lengths_and_workspaces_are_errors() {
    let model = urdf::model_from_str(DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap();
    let (nq, nv) = (model.nq(), model.nv());
    let mut ws = Workspace::new(&model);
    let (q, v) = (vec![0.1; 4 * nq], vec![0.2; 4 * nv]);
    let mut tau = vec![0.0; 4 * nv];
    let short = &v[..3 * nv];
    let got = rnea_rows(&model, &mut ws, &q, &v, short, &mut tau);
    assert!(
        matches!(
            got,
            Err((
                0,
                DynamicsError::Length {
                    vector: "a rows",
                    ..
                }
            ))
        ),
        "{got:?}"
    );
    let got = rnea_rows(&model, &mut ws, &q[..nq + 1], &v, &v, &mut tau);
    assert!(
        matches!(got, Err((0, DynamicsError::Length { .. }))),
        "{got:?}"
    );
    let other = urdf::model_from_str(LAMP_URDF, &ModelOptions::default()).unwrap();
    let got = rnea_rows(&other, &mut ws, &q, &v, &v, &mut tau);
    assert!(
        matches!(got, Err((0, DynamicsError::ForeignWorkspace { .. }))),
        "{got:?}"
    );
}
