//! `spatial_dynamics_c`: the library [`spatial_dynamics_core`] called in-process from C and C++
//! (a real-time ros2_control controller's `update()`, say), through the header
//! `include/spatial_dynamics.h` generated from this crate by cbindgen, and the header-only C++
//! wrapper `include/spatial_dynamics.hpp` over it.
//!
//! | module | holds |
//! |---|---|
//! | [`status`] | return codes, the thread's last error message, the guard every entry runs in |
//! | [`model`] | `sd_model`: a URDF model, its coordinate names and its forward-dynamics method |
//! | [`workspace`] | `sd_workspace`: the scratch of one model's calls |
//! | [`dynamics`] | inverse dynamics, gravity, forward dynamics, the mass matrix |
//! | [`derivatives`] | the derivatives of inverse and forward dynamics |
//! | [`frames`] | frame Jacobians |
//!
//! The conventions are the library's: SI units; `q` and `v` in the order of
//! `sd_model_v_name` (the order `spatial_dynamics model --json` lists), a floating base's
//! `q = [x y z qx qy qz qw]` and `v = [linear; angular]` in the base frame; matrices row-major.
//! Every function returns 0 on success, or a non-zero [`status`] code with a message for
//! `sd_last_error`; no panic crosses the boundary, a NULL pointer is an error, and no call
//! after a model and its workspace are made allocates.

//!
//! # Safety
//!
//! What every `unsafe extern "C"` function here requires of its caller (stated once here rather
//! than in each function's doc comment, which becomes the header's): each pointer is NULL (an
//! error, never dereferenced) or valid: a model or workspace made by this library and not yet
//! freed, an array of at least the length the function's doc gives, a NUL-terminated string;
//! a workspace is used by one thread at a time. An output array may be one of the inputs.

// The C names of the types are the header's (`sd_model`, ...).
#![allow(non_camel_case_types)]
// The contract is the crate's `# Safety` section above, the same for every function.
#![allow(clippy::missing_safety_doc)]

pub mod derivatives;
pub mod dynamics;
pub mod frames;
pub mod model;
pub mod status;
pub mod workspace;

pub use model::{sd_model, sd_model_options};
pub use workspace::sd_workspace;
