"""Simulate mode with a floating base: the node publishes the base's state on ~/base_state
(nav_msgs/Odometry: pose in the world, twist in the base frame) and, with `ground_contacts`,
lets the robot stand on a penalty-contact ground plane.

References are closed forms: a free body falls with z = z0 − g t²/2 and spins steadily about a
principal axis (torque-free), and a box resting on four springs of stiffness k sinks to
m g / (4 k) (the dampers are idle at rest).
"""

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Pose, Twist
from nav_msgs.msg import Odometry
from spatial_dynamics_msgs.srv import DescribeModel, Reset
from std_srvs.srv import SetBool, Trigger

import sd_dds_support as sd

NODE = "/spatial_dynamics"
MASS, G, K = 2.0, 9.81, 2e4
# A 0.2 × 0.1 × 0.04 m box whose link frame sits at the centre of its bottom face.
BOX_URDF = f"""<robot name="box">
  <link name="box">
    <inertial>
      <origin xyz="0 0 0.02"/>
      <mass value="{MASS}"/>
      <inertia ixx="{MASS * (0.1**2 + 0.04**2) / 12}" iyy="{MASS * (0.2**2 + 0.04**2) / 12}"
               izz="{MASS * (0.2**2 + 0.1**2) / 12}" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
</robot>"""
CORNERS = [f"box:{x},{y},0.0" for x in (0.1, -0.1) for y in (0.05, -0.05)]
DT = 0.001


def start(nodes, ros, tmp_path, label, extra="", expect_exit=False):
    params = tmp_path / f"{label}.yaml"
    params.write_text(
        "spatial_dynamics:\n  ros__parameters:\n"
        f"    robot_description: {sd.yaml_string(BOX_URDF)}\n"
        "    floating_base: true\n    mode: simulate\n    integrator: rk4\n"
        f"    sim_dt: {DT}\n    publish_rate: 50.0\n" + extra
    )
    node = nodes.start("--params-file", str(params), label=label, expect_exit=expect_exit)
    if not expect_exit:
        ros.wait_for_service(DescribeModel, f"{NODE}/describe_model")
    return node


def seconds(stamp):
    return stamp.sec + 1e-9 * stamp.nanosec


def test_a_free_body_falls_and_spins_as_the_closed_form_says(nodes, ros, tmp_path):
    start(nodes, ros, tmp_path, "free")
    assert ros.call(SetBool, f"{NODE}/pause", SetBool.Request(data=True)).success
    omega, z0, steps = 3.0, 1.5, 200
    pose, twist = Pose(), Twist()
    pose.position.z = z0
    twist.angular.z = omega  # about the box's principal z axis: a steady spin
    reset = ros.call(Reset, f"{NODE}/reset", Reset.Request(base_pose=pose, base_twist=twist))
    assert reset.success, reset.message
    states = ros.collector(Odometry, f"{NODE}/base_state", sd.qos_reliable())
    states.wait_publisher()
    for _ in range(steps):
        assert ros.call(Trigger, f"{NODE}/step", Trigger.Request()).success
    last = states.wait(n=steps, timeout=sd.EVENT_S)[-1]
    t = steps * DT
    assert last.header.frame_id == "world" and last.child_frame_id == "box"
    p, o = last.pose.pose.position, last.pose.pose.orientation
    # RK4 integrates constant acceleration and a constant-axis spin exactly (to rounding).
    np.testing.assert_allclose([p.x, p.y, p.z], [0.0, 0.0, z0 - 0.5 * G * t * t], atol=1e-9)
    np.testing.assert_allclose([o.x, o.y, o.z, o.w], [0.0, 0.0, math.sin(omega * t / 2), math.cos(omega * t / 2)], atol=1e-9)
    # Twist in the base frame: the world velocity (0, 0, −g t) seen from axes turned by ω t about z.
    lin, ang = last.twist.twist.linear, last.twist.twist.angular
    np.testing.assert_allclose([lin.x, lin.y, lin.z, ang.x, ang.y, ang.z], [0, 0, -G * t, 0, 0, omega], atol=1e-9)
    assert ros.call(SetBool, f"{NODE}/pause", SetBool.Request(data=False)).success


def test_the_box_rests_on_the_ground_at_the_static_penetration(nodes, ros, tmp_path):
    contacts = "[" + ", ".join(f"'{c}'" for c in CORNERS) + "]"
    start(nodes, ros, tmp_path, "ground", f"    ground_contacts: {contacts}\n    ground_stiffness: {K}\n")
    states = ros.collector(Odometry, f"{NODE}/base_state", sd.qos_best_effort())
    # Dropped at z = 0 (touching): after 1.5 simulated s the damped springs have settled.
    last = states.wait(timeout=sd.EVENT_S, predicate=lambda m: seconds(m.header.stamp) > 1.5)[-1]
    sink = MASS * G / (4 * K)
    p = last.pose.pose.position
    assert p.z == pytest.approx(-sink, rel=0.02), (p.z, -sink)
    assert abs(p.x) < 1e-6 and abs(p.y) < 1e-6
    diagnostics = ros.collector(DiagnosticArray, "/diagnostics")
    array = diagnostics.wait(n=2, timeout=sd.EVENT_S)[-1]
    values = {kv.key: kv.value for status in array.status for kv in status.values}
    assert float(values["deepest ground penetration (m)"]) >= sink * 0.98, values


@pytest.mark.parametrize(
    "case, extra, words",
    [
        ("stiffness", "    ground_stiffness: -5.0\n", ["ground_stiffness", "-5"]),
        ("friction", "    ground_friction: .nan\n", ["ground_friction", "NaN"]),
        ("link", "    ground_contacts: ['lid:0,0,0']\n", ["unknown link 'lid'"]),
        ("point", "    ground_contacts: ['box:0,0']\n", ["ground_contacts", "box:0,0"]),
    ],
)
def test_bad_ground_settings_stop_the_node_with_the_field_named(nodes, ros, tmp_path, case, extra, words):
    node = start(nodes, ros, tmp_path, case, extra, expect_exit=True)
    assert node.wait_exit(10.0) not in (0, None), node.describe()
    for word in words:
        assert word in node.log(), node.describe()
