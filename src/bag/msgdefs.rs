//! Message definitions for MCAP schemas (encoding `ros2msg`): the type's own `.msg` text, then
//! each type it uses after a line of 80 `=` and `MSG: package/Type`, as rosbag2 writes them.

const SEPARATOR: &str =
    "================================================================================\n";

const TIME: &str = "int32 sec\nuint32 nanosec\n";
const HEADER: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const JOINT_STATE: &str = "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n";

/// `sensor_msgs/msg/JointState` with its dependencies.
pub fn joint_state() -> String {
    with_header(JOINT_STATE)
}

/// `spatial_dynamics_msgs/msg/JointDynamics` (our `msg/msg/JointDynamics.msg`) with its dependencies.
pub fn joint_dynamics() -> String {
    with_header(include_str!("../../msg/msg/JointDynamics.msg"))
}

fn with_header(main: &str) -> String {
    let mut text = main.to_string();
    if !text.ends_with('\n') {
        text.push('\n');
    }
    for (name, body) in [
        ("std_msgs/Header", HEADER),
        ("builtin_interfaces/Time", TIME),
    ] {
        text.push_str(SEPARATOR);
        text.push_str("MSG: ");
        text.push_str(name);
        text.push('\n');
        text.push_str(body);
    }
    text
}
