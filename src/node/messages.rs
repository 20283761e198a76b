//! The shared message types ([`crate::ros::msgs`]) marked as ros2-client messages: the one
//! piece of them that needs the ROS stack.

use crate::ros::msgs::*;
use ros2_client::Message;

macro_rules! messages {
    ($($name:ident),* $(,)?) => { $(impl Message for $name {})* };
}

messages!(
    Time,
    Log,
    Duration,
    Header,
    StringMsg,
    MultiArrayDimension,
    MultiArrayLayout,
    Float64MultiArray,
    JointState,
    JointTrajectoryPoint,
    JointTrajectory,
    Vector3,
    Point,
    Quaternion,
    Pose,
    Twist,
    Accel,
    Wrench,
    PoseWithCovariance,
    TwistWithCovariance,
    Odometry,
    TransformMsg,
    TransformStamped,
    TFMessage,
    KeyValue,
    DiagnosticStatus,
    DiagnosticArray,
    JointDynamics,
    LinkWrench,
    InverseDynamicsRequest,
    InverseDynamicsResponse,
    ForwardDynamicsRequest,
    ForwardDynamicsResponse,
    MassMatrixRequest,
    MassMatrixResponse,
    Clock,
    SetBoolRequest,
    SetBoolResponse,
    TriggerRequest,
    TriggerResponse,
    ResetRequest,
    ResetResponse,
    DescribeModelRequest,
    DescribeModelResponse,
    FrameKinematicsRequest,
    FrameKinematicsResponse,
    LinearizeRequest,
    LinearizeResponse,
);
