"""ROS 2 launch file: the spatial_dynamics node with a parameters file and, given a URDF,
robot_state_publisher beside it.

    ros2 launch spatial_dynamics spatial_dynamics.launch.py
    ros2 launch spatial_dynamics spatial_dynamics.launch.py urdf:=/path/robot.urdf params_file:=my.yaml

Arguments:
  params_file  the node's parameters (default: the installed config/default.yaml, every
               parameter at its default); its entries are keyed by node name (`spatial_dynamics:`)
               or `/**`.
  urdf         a URDF file: its text is the `robot_description` of both the node and
               robot_state_publisher (which then publishes the robot's TF tree). Empty (the
               default): the node models what the params file names, or the embedded 7-joint
               arm, and no robot_state_publisher is started.
  namespace    a namespace for both nodes (default: none).
  node_name    the node's name (default: spatial_dynamics; a params file keyed by name must
               use the same one).

Installed by cargo-ament-build (`[package.metadata.ros] install_to_share` in Cargo.toml) to
share/spatial_dynamics/launch/.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = "spatial_dynamics"
EXECUTABLE = "spatial_dynamics_node"


def _nodes(context):
    """The nodes for the arguments given (read once the launch arguments are known)."""
    params_file = LaunchConfiguration("params_file").perform(context)
    urdf = LaunchConfiguration("urdf").perform(context)
    namespace = LaunchConfiguration("namespace").perform(context)
    node_name = LaunchConfiguration("node_name").perform(context)

    parameters = [params_file]
    nodes = []
    if urdf:
        with open(urdf, encoding="utf-8") as f:
            description = {"robot_description": f.read()}
        # Given last, the URDF's text wins over any robot_description in the params file.
        parameters.append(description)
        nodes.append(
            Node(
                package="robot_state_publisher",
                executable="robot_state_publisher",
                namespace=namespace,
                parameters=[description],
                output="screen",
            )
        )
    nodes.insert(
        0,
        Node(
            package=PACKAGE,
            executable=EXECUTABLE,
            name=node_name,
            namespace=namespace,
            parameters=parameters,
            output="screen",
        ),
    )
    return nodes


def generate_launch_description():
    share = get_package_share_directory(PACKAGE)
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "params_file",
                default_value=os.path.join(share, "config", "default.yaml"),
                description="the node's parameters file",
            ),
            DeclareLaunchArgument(
                "urdf",
                default_value="",
                description="URDF file: robot_description of the node and of robot_state_publisher",
            ),
            DeclareLaunchArgument("namespace", default_value="", description="namespace of both nodes"),
            DeclareLaunchArgument("node_name", default_value=PACKAGE, description="the node's name"),
            OpaqueFunction(function=_nodes),
        ]
    )
