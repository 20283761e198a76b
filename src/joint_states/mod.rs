//! One measured joint state in → gravity, acceleration, measured dynamics and effort residual
//! out: the code the live node (`joint_states` topic) and offline replay
//! (`spatial_dynamics replay`) share. No ROS stack: the node adds DDS around it, replay adds bag reading and writing.
//!
//! - [`joint_map`]: joint names ↔ the model's coordinates (the rules every message follows);
//! - [`commands`]: the latest commanded effort `τ_cmd`, from `~/effort_command` (by name) or
//!   `~/commands` (in `command_joints` order);
//! - [`differences`]: `q̈` estimated from the measured velocities by finite differences;
//! - [`dynamics`]: `g(q)`, `FD(q, q̇, τ_cmd)` and `RNEA(q, q̇, q̈)` of one state, by the library's
//!   combined evaluation;
//! - [`residual`]: the effort residual `τ_measured − RNEA(q, q̇, q̈)`, and its one-sample-late
//!   form for the live node.

pub mod commands;
pub mod differences;
pub mod dynamics;
pub mod joint_map;
pub mod residual;

/// Why a message was refused: a short kind (for counting, e.g. `"bad position"`) and a message
/// naming the joint, field or value.
pub type Rejection = (&'static str, String);
