//! The position- and velocity-dependent parts shared by every algorithm, one module per kind of
//! quantity: the joint transforms (`joints`: `jcalc` for each joint, then
//! `ⁱX_λ(i) = X_J X_tree`), the bodies' placements in the world (`placements`), the aligned
//! frames of the passes that work in world coordinates (`aligned`) and the bodies' velocities
//! (`velocities`).

mod aligned;
mod joints;
mod placements;
mod velocities;

pub(crate) use aligned::{
    force_across_anchor, force_out_of_aligned, motion_across_anchor, motion_into_aligned,
    update_aligned_placements, update_world_axes, world_axes, Anchors,
};
pub(crate) use joints::{read_joint, update_joints, update_up, with_up_transform};
pub use placements::body_placements;
pub(crate) use placements::update_placements;
pub use velocities::body_motion;
pub(crate) use velocities::update_velocities;
