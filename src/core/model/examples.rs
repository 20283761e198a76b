//! Built-in example models: the URDFs in `config/models/` (embedded in the binary) and a
//! generator for n-link pendulums.

/// The embedded default robot: `sd_arm7`, a 7-DOF arm (see `config/models/README.md`).
pub const DEFAULT_ARM_URDF: &str = include_str!("../../../config/models/default_arm.urdf");
/// The handout's particle: a point mass on two massless prismatic joints (x, then z).
pub const PARTICLE_URDF: &str = include_str!("../../../config/models/particle.urdf");
/// The handout's 2-D jumping lamp: a planar base and two hinges.
pub const LAMP_URDF: &str = include_str!("../../../config/models/lamp.urdf");
/// A small gripper with mimic joints.
pub const MIMIC_GRIPPER_URDF: &str = include_str!("../../../config/models/mimic_gripper.urdf");

/// URDF of a planar pendulum of `n` identical links hanging from the world: continuous joints
/// `joint1…joint<n>` about y, each link a thin rod of `length` (m) and `mass` (kg) along −z, its
/// centre of mass at the middle, its inertia that of a thin rod (`m l² / 12` about x and y, a
/// small `1e-6 m l²` about its own axis so the tensor is positive definite).
pub fn pendulum_urdf(n: usize, length: f64, mass: f64) -> String {
    let rod = mass * length * length / 12.0;
    let spin = 1e-6 * mass * length * length;
    let mut urdf = format!("<robot name=\"pendulum{n}\">\n  <link name=\"world\"/>\n");
    for i in 1..=n {
        let parent = if i == 1 {
            "world".to_string()
        } else {
            format!("link{}", i - 1)
        };
        let z = if i == 1 { 0.0 } else { -length };
        urdf += &format!(
            "  <joint name=\"joint{i}\" type=\"continuous\">\n    <parent link=\"{parent}\"/>\n    <child link=\"link{i}\"/>\n    <origin xyz=\"0 0 {z}\"/>\n    <axis xyz=\"0 1 0\"/>\n  </joint>\n  <link name=\"link{i}\">\n    <inertial>\n      <origin xyz=\"0 0 {c}\"/>\n      <mass value=\"{mass}\"/>\n      <inertia ixx=\"{rod}\" ixy=\"0\" ixz=\"0\" iyy=\"{rod}\" iyz=\"0\" izz=\"{spin}\"/>\n    </inertial>\n  </link>\n",
            c = -length / 2.0
        );
    }
    urdf + "</robot>\n"
}
