//! The passes against each other: body and world coordinates, both mirror forms and the
//! general pass give the same `H`; an overflow is reported in either frame.

use super::*;
use crate::model::examples::{self, pendulum_urdf};
use crate::sampling::{random_q, Rng};
use crate::{urdf, ModelOptions};

const TREE: &str = include_str!("../../tests/models/tree.urdf");
const TURN_SLIDE: &str = include_str!("../../tests/models/turn_slide.urdf");

fn load(text: &str, floating_base: bool) -> Model {
    let options = ModelOptions {
        floating_base,
        ..Default::default()
    };
    urdf::model_from_str(text, &options).unwrap()
}

/// `H` by the row blocks in world and in body coordinates, and by the general pass along
/// the paths, on trees with every joint kind (planar and floating roots, axes on and off
/// the coordinate axes, prismatic joints), agree to rounding and are exactly symmetric.
#[test]
fn world_and_body_frames_and_the_general_pass_agree() {
    let models = [
        load(TREE, false),
        load(
            &TREE.replace(r#"type="planar""#, r#"type="floating""#),
            false,
        ),
        load(&pendulum_urdf(9, 0.5, 0.7), false),
        load(&pendulum_urdf(20, 0.5, 0.7), true), // mirrored by three tiles of rows
        load(examples::DEFAULT_ARM_URDF, false),
        load(examples::DEFAULT_ARM_URDF, true),
        load(examples::LAMP_URDF, true),
    ];
    for model in &models {
        let mut ws = Workspace::new(model);
        let subtree_end = ws.plan.subtree_end.clone();
        assert!(subtree_end.is_some(), "{}", model.name);
        let mut rng = Rng::new(21);
        for _ in 0..5 {
            let q = random_q(model, &mut rng);
            let mut h = Vec::new();
            for (frames, subtree_end, tiles) in [
                (CrbaFrames::World, subtree_end.clone(), false),
                (CrbaFrames::World, subtree_end.clone(), true),
                (CrbaFrames::Local, subtree_end.clone(), false),
                (CrbaFrames::Local, subtree_end.clone(), true),
                (CrbaFrames::World, None, false), // the general pass
            ] {
                (ws.plan.crba_frames, ws.plan.subtree_end) = (frames, subtree_end);
                ws.plan.mirror_by_tiles = tiles;
                ws.mass_matrix.fill(0.0); // an entry a pass misses stays 0
                let m = crba(model, &mut ws, &q).unwrap();
                assert_eq!(m, &m.transpose(), "{}: {frames:?}", model.name);
                h.push(m.clone());
            }
            // The mirror's two forms give the same matrix, bit for bit.
            assert_eq!(h[0], h[1], "{}: world rows", model.name);
            assert_eq!(h[2], h[3], "{}: body rows", model.name);
            let scale = h[0].amax();
            for other in &h[1..] {
                let err = (&h[0] - other).amax();
                assert!(err < 1e-13 * scale, "{}: H differs by {err:e}", model.name);
            }
        }
    }
}

/// An entry that overflows is found in either frame (`m x²` for a slide at `x = 1e200`).
#[test]
fn overflow_is_found_in_both_frames() {
    let model = load(TURN_SLIDE, false);
    let mut ws = Workspace::new(&model);
    for frames in [CrbaFrames::World, CrbaFrames::Local] {
        ws.plan.crba_frames = frames;
        let err = crba(&model, &mut ws, &[0.0, 1e200]).unwrap_err();
        assert!(
            matches!(err, DynamicsError::NonFiniteResult { .. }),
            "{frames:?}: {err}"
        );
    }
}
