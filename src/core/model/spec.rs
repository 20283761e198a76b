//! What a model is built from and how: links and joints as a description gives them, and the
//! choices (floating base, mimic handling, gravity, reductions) applied while building. Shared by
//! the builder and the reductions; knows nothing of either.

use super::{JointKind, JointLimits};
use crate::spatial::{Inertia, Transform, Vector3};

/// A link: its name and its spatial inertia in the link frame.
#[derive(Clone, Debug)]
pub struct BodySpec {
    pub name: String,
    pub inertia: Inertia,
}

/// A joint between two links.
#[derive(Clone, Debug)]
pub struct JointSpec {
    pub name: String,
    pub parent: String,
    pub child: String,
    /// Transform from the parent link frame to the joint frame (which is the child link frame
    /// when the joint is at zero).
    pub origin: Transform,
    /// `None` for a fixed joint.
    pub kind: Option<JointKind>,
    /// `(leader joint, multiplier, offset)` for a mimic joint.
    pub mimic: Option<(String, f64, f64)>,
    pub limits: JointLimits,
}

/// Choices made when a model is built.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelOptions {
    /// Add a floating joint between the world and the root link.
    pub floating_base: bool,
    /// Treat mimic joints as independent joints with coordinates of their own.
    pub ignore_mimic: bool,
    /// Gravity in world coordinates (m/s²).
    pub gravity: Vector3,
    /// Joints frozen at a position: each becomes fixed and its child link fuses into the parent
    /// body (a mimic follower of a locked leader is locked with it; a follower may be locked only
    /// with its leader held, at `multiplier · leader + offset`). Each joint at most once; a
    /// revolute or prismatic joint within its limits when it has a range (`lower < upper`).
    pub locked: Vec<(String, f64)>,
    /// Keep only the subtree below this link (it becomes the fixed base): every joint outside
    /// it is frozen at its `locked` value or neutral position, and its links are fixed to the
    /// world. `None`: the description's root.
    pub root: Option<String>,
    /// Keep only the joints on the paths from the root to these links: the rest freeze, and
    /// the bodies past each tip become a payload lumped onto it. Empty: the whole subtree.
    pub tips: Vec<String>,
    /// Remove moving joints whose whole subtree has zero inertia (with their coordinates).
    pub prune_massless: bool,
}

impl Default for ModelOptions {
    fn default() -> Self {
        ModelOptions {
            floating_base: false,
            ignore_mimic: false,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            locked: Vec::new(),
            root: None,
            tips: Vec::new(),
            prune_massless: false,
        }
    }
}

/// Parses `NAME=POSITION` (a joint and a finite position, as `--lock` and the node's
/// `locked_joints` and `initial_positions` take them).
pub fn joint_position(spec: &str) -> Result<(String, f64), String> {
    spec.split_once('=')
        .and_then(|(n, v)| {
            Some((
                n.trim().to_string(),
                v.trim().parse::<f64>().ok().filter(|x| x.is_finite())?,
            ))
        })
        .filter(|(n, _)| !n.is_empty())
        .ok_or_else(|| format!("'{spec}' must be NAME=POSITION with a finite position"))
}
