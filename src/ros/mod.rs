//! ROS 2 conventions that need no ROS stack: the message types as plain serde structs and the
//! resolution of names. Shared by the node (which adds DDS) and offline bag replay.

pub mod msgs;
pub mod names;
