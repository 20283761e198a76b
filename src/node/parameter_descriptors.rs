//! What `describe_parameters` says of each parameter: a description, its constraints in words,
//! a numeric range where the value is one number with a range (a double's or an integer's), and
//! whether it is read-only (see [`super::params`] for the values and their checks; the ranges
//! here are the ones those checks enforce).

use super::params::{MAX_PUBLISH_RATE, MIN_PUBLISH_RATE, START_PARAMETERS};
use ros2_client::parameters::{NumericRange, ParameterDescriptor};
use ros2_client::ParameterValue;

/// A range `[from, to]` of doubles (rcl_interfaces/FloatingPointRange: inclusive, step 0 = any).
const fn doubles(from_value: f64, to_value: f64) -> NumericRange {
    NumericRange::FloatingPointRange {
        from_value,
        to_value,
        step: 0.0,
    }
}

/// A range `[from, to]` of integers (rcl_interfaces/IntegerRange: inclusive, step 0 = any).
const fn integers(from_value: i64, to_value: i64) -> NumericRange {
    NumericRange::IntegerRange {
        from_value,
        to_value,
        step: 0,
    }
}

const NONE: NumericRange = NumericRange::NotSpecified;
/// Seconds ≥ 0.
const SECONDS: NumericRange = doubles(0.0, f64::MAX);
/// A positive number (the smallest positive double is the inclusive bound of "> 0").
const POSITIVE: NumericRange = doubles(f64::MIN_POSITIVE, f64::MAX);

/// `(description, additional constraints, range)` of parameter `name`.
fn text(name: &str) -> (&'static str, &'static str, NumericRange) {
    match name {
        "robot_description" => ("URDF text of the robot. When set it wins over urdf_file and over the robot_description topic.", "URDF XML; a value that does not give a usable model is refused", NONE),
        "urdf_file" => ("Path of a URDF file, used when robot_description is empty (it wins over the robot_description topic).", "a readable URDF file; a value that does not give a usable model is refused", NONE),
        "floating_base" => ("Add a floating (free 6-DoF) joint between the world and the root link, for legged robots and humanoids.", "", NONE),
        "ignore_mimic" => ("Treat <mimic> joints as independent joints instead of followers of their leader.", "", NONE),
        "locked_joints" => ("Joints held at a fixed position and fused into their parent body, as NAME=POSITION (rad or m).", "each entry NAME=POSITION naming a joint of the model", NONE),
        "root_link" => ("Keep only the subtree of this link, which becomes the fixed base; empty: the URDF's root.", "a link of the URDF or empty", NONE),
        "tip_links" => ("Keep only the joints from the root to these links; bodies beyond a tip are lumped onto it.", "links of the URDF", NONE),
        "prune_massless" => ("Remove moving joints whose whole subtree has no mass.", "", NONE),
        "gravity" => ("Gravity acceleration in the world frame [x, y, z], m/s^2.", "three finite numbers", NONE),
        "method" => ("Forward-dynamics method: aba, crba, rnea_columns, or auto (of the methods whose accelerations agree with aba to 1e-10 on sampled states of this model, the one with the fewest floating-point operations per call; chosen when the model loads, the same on every run).", "one of auto, aba, crba, rnea_columns", NONE),
        "command_joints" => ("Order of the joints in ~/commands and ~/feedforward_commands; empty: every joint in model order.", "coordinate names of the model (a planar joint J as J/x, J/y, J/theta)", NONE),
        "use_sim_time" => ("The node's clock is ROS simulated time: the latest /clock (in simulate mode, its own simulated time); outputs are stamped with it.", "", NONE),
        "max_stamp_age" => ("Drop a joint_states message stamped more than this before the node's clock, s; 0: no limit.", "0 or seconds >= 1e-9", SECONDS),
        "future_stamp_tolerance" => ("Drop a joint_states message stamped more than this after the node's clock, s; 0: no limit.", "0 or seconds >= 1e-9", SECONDS),
        "mode" => ("serve: the dynamics of the measured state (joint_states in, efforts and accelerations out); simulate: the node owns the state, integrates it and publishes joint_states.", "serve or simulate", NONE),
        "publish_rate" => ("Simulate mode: joint_states messages per second, Hz.", "0.001 to 1e6; at most 1e6 steps of sim_dt per message (real_time_factor / (publish_rate · sim_dt))", doubles(MIN_PUBLISH_RATE, MAX_PUBLISH_RATE)),
        "sim_dt" => ("Simulate mode: integration step, s.", "> 0; at most 1e6 steps per joint_states message", POSITIVE),
        "integrator" => ("Simulate mode: explicit_euler, semi_implicit_euler, rk4 or implicit_euler.", "one of explicit_euler, semi_implicit_euler, rk4, implicit_euler", NONE),
        "real_time_factor" => ("Simulate mode: simulated seconds per wall-clock second.", "> 0; at most 1e6 steps of sim_dt per joint_states message", POSITIVE),
        "publish_clock" => ("Simulate mode: publish the simulated time on /clock.", "", NONE),
        "command_timeout" => ("Simulate mode: a command (effort, or position or velocity servo targets) older than this (wall-clock s) drops to zero effort, the servos off; 0: never; not used with step_mode on_command.", "seconds >= 0", SECONDS),
        "command_interface" => ("Simulate mode: what ~/commands and ~/joint_commands set on each command joint: effort (the effort itself), position (PD servo: kp (q_cmd - q) + kd (qd_cmd - qd)) or velocity (kd (qd_cmd - qd)).", "one of effort, position, velocity", NONE),
        "servo_kp" => ("Simulate mode, position interface: servo position gains, N*m/rad or N/m; one value for every command joint or one per command_joints entry.", "finite gains >= 0, one or as many as command joints", NONE),
        "servo_kd" => ("Simulate mode, position and velocity interfaces: servo rate gains, N*m*s/rad or N*s/m; one value for every command joint or one per command_joints entry.", "finite gains >= 0, one or as many as command joints", NONE),
        "step_mode" => ("Simulate mode: free (the publish timer advances the state in real time) or on_command (each accepted command advances it by sim_dt * steps_per_command and publishes once; nothing moves without a command).", "free or on_command", NONE),
        "steps_per_command" => ("Simulate mode, step_mode on_command: integration steps of sim_dt per accepted command.", "integer 1 to 1000000", integers(1, 1_000_000)),
        "publish_tf" => ("Simulate mode: with a floating base, publish world -> base link on /tf with each joint state.", "", NONE),
        "passive" => ("Simulate mode: the URDF's passive forces applied: damping, friction, effort_limits, position_limits (or all, none).", "names from damping, friction, effort_limits, position_limits, all, none", NONE),
        "initial_positions" => ("Simulate mode: the state at start and whenever the model is rebuilt, as NAME=POSITION (rad or m); other joints start at zero.", "each entry NAME=POSITION naming a joint of the model", NONE),
        "ground_contacts" => ("Simulate mode: points LINK:X,Y,Z (link frame, m) that touch a ground plane; empty: no ground.", "each entry LINK:X,Y,Z naming a link of the model", NONE),
        "ground_height" => ("Simulate mode: the ground plane is z = ground_height in the world frame, m.", "finite", doubles(-f64::MAX, f64::MAX)),
        "ground_stiffness" => ("Simulate mode: contact stiffness per point, N/m.", "> 0", POSITIVE),
        "ground_damping" => ("Simulate mode: contact damping per point, N*s/m.", ">= 0", doubles(0.0, f64::MAX)),
        "ground_friction" => ("Simulate mode: Coulomb friction coefficient of the contacts.", ">= 0", doubles(0.0, f64::MAX)),
        _ => ("", "", NONE),
    }
}

/// The descriptor of parameter `name` holding `value` (its type is the value's).
pub fn descriptor(name: &str, value: &ParameterValue) -> ParameterDescriptor {
    let (description, constraints, range) = text(name);
    let read_only = START_PARAMETERS.contains(&name);
    let mut additional_constraints = constraints.to_string();
    if read_only {
        if !additional_constraints.is_empty() {
            additional_constraints += "; ";
        }
        additional_constraints += "read-only: read when the simulation is built";
    }
    ParameterDescriptor {
        description: description.to_string(),
        additional_constraints,
        read_only,
        range,
        ..ParameterDescriptor::from_value(name, value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::params::{Settings, NAMES};

    #[test]
    fn every_parameter_is_described_and_ranges_hold_the_defaults() {
        let settings = Settings::default();
        for name in NAMES {
            let value = settings.get(name).expect("every parameter has a value");
            let d = descriptor(name, &value);
            assert!(!d.description.is_empty(), "{name} has no description");
            match (d.range, &value) {
                (NumericRange::NotSpecified, _) => {}
                (
                    NumericRange::FloatingPointRange {
                        from_value,
                        to_value,
                        ..
                    },
                    &ParameterValue::Double(x),
                ) => assert!(
                    from_value <= x && x <= to_value,
                    "{name} = {x} out of its range"
                ),
                (
                    NumericRange::IntegerRange {
                        from_value,
                        to_value,
                        ..
                    },
                    &ParameterValue::Integer(n),
                ) => assert!(
                    from_value <= n && n <= to_value,
                    "{name} = {n} out of its range"
                ),
                (range, value) => panic!("{name}: range {range:?} on the value {value:?}"),
            }
        }
        assert!(descriptor("mode", &ParameterValue::String("serve".into())).read_only);
        assert!(!descriptor("publish_clock", &ParameterValue::Boolean(false)).read_only);
    }
}
