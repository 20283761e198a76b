//! Models the unit tests share.

use crate::model::ModelOptions;

/// The branched test tree (`src/core/tests/models/tree.urdf`): a planar base with two arms
/// (revolute then prismatic; continuous, fixed, revolute) and a head (revolute).
pub(crate) const TREE_URDF: &str = include_str!("tests/models/tree.urdf");

/// Options that put the model on a floating base.
pub(crate) fn floating() -> ModelOptions {
    ModelOptions {
        floating_base: true,
        ..ModelOptions::default()
    }
}
