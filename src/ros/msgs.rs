//! ROS 2 message and service types, as serde structs laid out field by field like their `.msg`
//! definitions (CDR serialises them in declaration order). Plain data: the node marks them as
//! ros2-client messages (`src/node/messages.rs`); offline replay and the bag code use them
//! without any ROS crate.

use serde::{Deserialize, Serialize};

macro_rules! ros_message {
    ($($(#[$doc:meta])* $name:ident { $($field:ident : $ty:ty),* $(,)? })*) => {
        $(
            $(#[$doc])*
            #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
            pub struct $name { $(pub $field: $ty),* }
        )*
    };
}

ros_message! {
    /// builtin_interfaces/Time
    Time { sec: i32, nanosec: u32 }
    /// builtin_interfaces/Duration
    Duration { sec: i32, nanosec: u32 }
    /// std_msgs/Header
    Header { stamp: Time, frame_id: String }
    /// std_msgs/String
    StringMsg { data: String }
    /// std_msgs/MultiArrayDimension
    MultiArrayDimension { label: String, size: u32, stride: u32 }
    /// std_msgs/MultiArrayLayout
    MultiArrayLayout { dim: Vec<MultiArrayDimension>, data_offset: u32 }
    /// std_msgs/Float64MultiArray
    Float64MultiArray { layout: MultiArrayLayout, data: Vec<f64> }
    /// sensor_msgs/JointState
    JointState { header: Header, name: Vec<String>, position: Vec<f64>, velocity: Vec<f64>, effort: Vec<f64> }
    /// trajectory_msgs/JointTrajectoryPoint
    JointTrajectoryPoint { positions: Vec<f64>, velocities: Vec<f64>, accelerations: Vec<f64>, effort: Vec<f64>, time_from_start: Duration }
    /// trajectory_msgs/JointTrajectory
    JointTrajectory { header: Header, joint_names: Vec<String>, points: Vec<JointTrajectoryPoint> }
    /// geometry_msgs/Vector3
    Vector3 { x: f64, y: f64, z: f64 }
    /// geometry_msgs/Point
    Point { x: f64, y: f64, z: f64 }
    /// geometry_msgs/Pose
    Pose { position: Point, orientation: Quaternion }
    /// geometry_msgs/Twist
    Twist { linear: Vector3, angular: Vector3 }
    /// geometry_msgs/Accel
    Accel { linear: Vector3, angular: Vector3 }
    /// geometry_msgs/Wrench
    Wrench { force: Vector3, torque: Vector3 }
    /// geometry_msgs/PoseWithCovariance
    PoseWithCovariance { pose: Pose, covariance: Covariance }
    /// geometry_msgs/TwistWithCovariance
    TwistWithCovariance { twist: Twist, covariance: Covariance }
    /// geometry_msgs/Transform
    TransformMsg { translation: Vector3, rotation: Quaternion }
    /// geometry_msgs/TransformStamped
    TransformStamped { header: Header, child_frame_id: String, transform: TransformMsg }
    /// tf2_msgs/TFMessage
    TFMessage { transforms: Vec<TransformStamped> }
    /// nav_msgs/Odometry
    Odometry { header: Header, child_frame_id: String, pose: PoseWithCovariance, twist: TwistWithCovariance }
    /// diagnostic_msgs/KeyValue
    KeyValue { key: String, value: String }
    /// diagnostic_msgs/DiagnosticStatus
    DiagnosticStatus { level: u8, name: String, message: String, hardware_id: String, values: Vec<KeyValue> }
    /// diagnostic_msgs/DiagnosticArray
    DiagnosticArray { header: Header, status: Vec<DiagnosticStatus> }
    /// spatial_dynamics_msgs/JointDynamics
    JointDynamics { header: Header, name: Vec<String>, position: Vec<f64>, velocity: Vec<f64>, acceleration: Vec<f64>, effort: Vec<f64> }
    /// spatial_dynamics_msgs/LinkWrench
    LinkWrench { link: String, frame: String, wrench: Wrench }
    /// spatial_dynamics_msgs/InverseDynamics request
    InverseDynamicsRequest { name: Vec<String>, position: Vec<f64>, velocity: Vec<f64>, acceleration: Vec<f64>, external_wrenches: Vec<LinkWrench>, base_pose: Pose, base_twist: Twist, base_accel: Accel }
    /// spatial_dynamics_msgs/InverseDynamics response
    InverseDynamicsResponse { success: bool, message: String, name: Vec<String>, effort: Vec<f64>, base_wrench: Wrench }
    /// spatial_dynamics_msgs/ForwardDynamics request
    ForwardDynamicsRequest { name: Vec<String>, position: Vec<f64>, velocity: Vec<f64>, effort: Vec<f64>, external_wrenches: Vec<LinkWrench>, method: String, base_pose: Pose, base_twist: Twist, base_wrench: Wrench }
    /// spatial_dynamics_msgs/ForwardDynamics response
    ForwardDynamicsResponse { success: bool, message: String, name: Vec<String>, acceleration: Vec<f64>, base_accel: Accel }
    /// spatial_dynamics_msgs/MassMatrix request
    MassMatrixRequest { name: Vec<String>, position: Vec<f64>, base_pose: Pose }
    /// spatial_dynamics_msgs/MassMatrix response
    MassMatrixResponse { success: bool, message: String, name: Vec<String>, matrix: Vec<f64> }
    /// rosgraph_msgs/Clock
    Clock { clock: Time }
    /// rcl_interfaces/Log (what `/rosout` carries; `level` is rcutils' severity: 10 … 50)
    Log { stamp: Time, level: u8, name: String, msg: String, file: String, function: String, line: u32 }
    /// std_srvs/SetBool request
    SetBoolRequest { data: bool }
    /// std_srvs/SetBool response
    SetBoolResponse { success: bool, message: String }
    /// std_srvs/Trigger request (an empty message: one placeholder byte on the wire)
    TriggerRequest { structure_needs_at_least_one_member: u8 }
    /// std_srvs/Trigger response
    TriggerResponse { success: bool, message: String }
    /// spatial_dynamics_msgs/Reset request
    ResetRequest { name: Vec<String>, position: Vec<f64>, velocity: Vec<f64>, base_pose: Pose, base_twist: Twist }
    /// spatial_dynamics_msgs/Reset response
    ResetResponse { success: bool, message: String }
    /// spatial_dynamics_msgs/DescribeModel request
    DescribeModelRequest { unused: u8 }
    /// spatial_dynamics_msgs/DescribeModel response
    DescribeModelResponse {
        success: bool, message: String, joint_names: Vec<String>, joint_types: Vec<String>,
        position_lower: Vec<f64>, position_upper: Vec<f64>, velocity_limit: Vec<f64>, effort_limit: Vec<f64>,
        link_names: Vec<String>, nq: u32, nv: u32, floating_base: bool, gravity: Vector3, method: String,
        locked_joints: Vec<String>, fused_links: Vec<String>
    }
    /// spatial_dynamics_msgs/FrameKinematics request
    FrameKinematicsRequest {
        name: Vec<String>, position: Vec<f64>, velocity: Vec<f64>, acceleration: Vec<f64>,
        base_pose: Pose, base_twist: Twist, base_accel: Accel, links: Vec<String>, reference: String
    }
    /// spatial_dynamics_msgs/FrameKinematics response
    FrameKinematicsResponse {
        success: bool, message: String, links: Vec<String>, poses: Vec<Pose>, columns: Vec<String>,
        jacobians: Vec<f64>, accelerations: Vec<Accel>, mass: f64, center_of_mass: Point,
        center_of_mass_jacobian: Vec<f64>
    }
    /// spatial_dynamics_msgs/Linearize request
    LinearizeRequest {
        name: Vec<String>, position: Vec<f64>, velocity: Vec<f64>, effort: Vec<f64>, dt: f64,
        base_pose: Pose, base_twist: Twist, base_wrench: Wrench
    }
    /// spatial_dynamics_msgs/Linearize response
    LinearizeResponse {
        success: bool, message: String, columns: Vec<String>, dt: f64, effort: Vec<f64>,
        acceleration: Vec<f64>, a: Vec<f64>, b: Vec<f64>, ddq_dq: Vec<f64>, ddq_dv: Vec<f64>,
        minv: Vec<f64>
    }
}

/// geometry_msgs/Quaternion; its default is the identity (`w = 1`), as the .msg declares.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// A 6×6 covariance, `float64[36]` (a fixed-size array: serialised without a length).
#[derive(Clone, Debug, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Covariance([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut t = s.serialize_tuple(36)?;
        for x in &self.0 {
            t.serialize_element(x)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("36 float64 values")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (i, x) in c.iter_mut().enumerate() {
                    *x = seq
                        .next_element()?
                        .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, Visit)
    }
}

impl From<&Vector3> for nalgebra::Vector3<f64> {
    fn from(v: &Vector3) -> Self {
        nalgebra::Vector3::new(v.x, v.y, v.z)
    }
}

impl From<nalgebra::Vector3<f64>> for Vector3 {
    fn from(v: nalgebra::Vector3<f64>) -> Self {
        Vector3 {
            x: v.x,
            y: v.y,
            z: v.z,
        }
    }
}
