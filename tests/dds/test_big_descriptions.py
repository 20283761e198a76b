"""Big robot descriptions reaching the node: a 4 000-link chain on the latched robot_description
topic and a 4 000-link tree as the robot_description parameter are loaded and served; 50 MB descriptions (a huge comment: loads; 170 000
links: refused, naming the limit) on the topic and as a parameter leave the node alive and
serving, the old model kept when the new one is refused. Times are printed (pytest -s).
The 4 000-link answers are checked against the statics of the robot written out here (checked in
turn against Pinocchio on 12-link versions).
"""

import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from spatial_dynamics_msgs.srv import DescribeModel, InverseDynamics
from std_msgs.msg import Float64MultiArray, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

DM = "/spatial_dynamics/describe_model"
ID = "/spatial_dynamics/inverse_dynamics"
STATUS = "spatial_dynamics: dynamics"
BIG = 50 << 20
LINKS = 4_000


def link(name):
    return (
        f'<link name="{name}"><inertial><origin xyz="0 0 -0.05"/><mass value="1"/>'
        '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/></inertial></link>'
    )


def joint(i, parent, child):
    axis = ["1 0 0", "0 1 0", "0 0 1"][i % 3]
    return (
        f'<joint name="j{i}" type="continuous"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 -0.1" rpy="0.1 0 0"/><axis xyz="{axis}"/></joint>'
    )


def robot(n, parent):
    """The same robots as tests/big_inputs.rs: n links under `world`, link i hanging from parent(i)."""
    parts = ['<robot name="big"><link name="world"/>']
    for i in range(1, n + 1):
        p = parent(i)
        parts.append(link(f"l{i}"))
        parts.append(joint(i, "world" if p == 0 else f"l{p}", f"l{i}"))
    parts.append("</robot>")
    return "".join(parts)


def many_links(size):
    parts, i, length = ['<robot name="many"><link name="l0"/>'], 0, 0
    while length < size:
        i += 1
        parts.append(link(f"l{i}") + joint(i, f"l{i - 1}", f"l{i}"))
        length += len(parts[-1])
    parts.append("</robot>")
    return "".join(parts), i


def served(ros, n, timeout):
    """Polls ~/inverse_dynamics with a one-value request until the node refuses it for a model of
    `n` names (a short answer: replies of hundreds of kB from the node to rclpy are slow or lost
    with Fast DDS's default socket buffers); returns the seconds it took."""
    start = time.monotonic()
    last = None
    while time.monotonic() - start < timeout:
        last = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=[], position=[0.0]))
        if f"position has 1 values for {n} names" in last.message:
            return time.monotonic() - start
        ros.spin_for(0.5)
    raise AssertionError(f"not serving a {n}-coordinate model within {timeout} s; last answer: {str(last)[:300]}")


def rodrigues(axis, angle):
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]], float)
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def gravity_torques(n, parent, q):
    """g(q) of robot(n, parent) by statics, written out here: link i's joint frame is its parent's
    turned by Rx(0.1) and moved 0.1 m down, then turned about the joint axis by q_i; each link is
    1 kg with its centre 0.05 m below its joint; the torque holding joint k is minus the moment,
    about its axis, of the weight of everything it carries (Pinocchio cannot build a 4 000-link
    model here: its reader overflows the stack on the chain and its data runs out of memory; this
    is checked against it on small robots below)."""
    g = np.array([0.0, 0.0, -9.81])
    rx = rodrigues([1.0, 0.0, 0.0], 0.1)
    rot, pos = {0: np.eye(3)}, {0: np.zeros(3)}
    axis_w, com = {}, {}
    for i in range(1, n + 1):
        p = parent(i)
        axis = np.eye(3)[i % 3]
        pos[i] = pos[p] + rot[p] @ np.array([0.0, 0.0, -0.1])
        rot[i] = rot[p] @ rx @ rodrigues(axis, q[i - 1])
        axis_w[i] = rot[i] @ axis
        com[i] = pos[i] + rot[i] @ np.array([0.0, 0.0, -0.05])
    mass_sum = {i: 1.0 for i in range(1, n + 1)}
    com_sum = {i: com[i].copy() for i in range(1, n + 1)}
    for i in range(n, 1, -1):  # children come after their parents: subtree sums
        p = parent(i)
        if p:
            mass_sum[p] += mass_sum[i]
            com_sum[p] += com_sum[i]
    return np.array([-axis_w[k] @ np.cross(com_sum[k] - mass_sum[k] * pos[k], g) for k in range(1, n + 1)])


@pytest.mark.parametrize("shape", ["chain", "tree"])
def test_the_statics_reference_equals_pinocchio_on_small_robots(shape):
    parent = (lambda i: i - 1) if shape == "chain" else (lambda i: i // 2)
    n = 12
    ref = sd.PinRef(urdf_text=robot(n, parent))
    names = [f"j{i}" for i in range(1, n + 1)]
    q = [float(x) for x in np.random.default_rng(2).uniform(-1.5, 1.5, n)]
    assert_close(gravity_torques(n, parent, q), ref.pick(ref.gravity(ref.q(names, q)), names), f"{shape} statics")


def check_gravity(ros, n, parent, label):
    """A reference naming every joint goes in (hundreds of kB); ~/feedforward_commands comes out
    for three command_joints (first, middle, last) and equals the statics reference there."""
    names = [f"j{i}" for i in range(1, n + 1)]
    picked = [1, n // 2, n]
    result = ros.set_parameter("command_joints", [f"j{i}" for i in picked])
    assert result.successful, result.reason
    out = ros.collector(Float64MultiArray, "/spatial_dynamics/feedforward_commands")
    out.wait_publisher()
    pub = ros.publisher(JointTrajectory, "/spatial_dynamics/reference", sd.qos_reliable(10))
    q = [float(x) for x in np.random.default_rng(1).uniform(-1.5, 1.5, n)]
    msg = JointTrajectory(joint_names=names, points=[JointTrajectoryPoint(positions=q)])
    start = time.monotonic()
    got = ros.exchange(lambda: pub.publish(msg), out, lambda m: len(m.data) == 3, timeout=60.0, period=2.0)
    print(f"{label}: reference with {n} joints answered in {time.monotonic() - start:.2f} s")
    want = gravity_torques(n, parent, q)
    assert_close(got.data, [want[i - 1] for i in picked], f"{label}: gravity at joints {picked}", tol=1e-8)


def arm_still_served(ros):
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=ARM_JOINTS, position=[0.1] * 7))
    assert resp.success and list(resp.name) == ARM_JOINTS, resp.message


def test_ten_thousand_link_chain_on_the_topic_is_served(nodes, ros, latched):
    nodes.start(label="arm")
    text = robot(LINKS, lambda i: i - 1)
    start = time.monotonic()
    latched(subscribed=True).publish(String(data=text))
    served(ros, LINKS, 90.0)
    print(f"chain ({len(text) / 1e6:.1f} MB) on the topic: served after {time.monotonic() - start:.1f} s")
    check_gravity(ros, LINKS, lambda i: i - 1, "chain")


def test_ten_thousand_link_tree_as_the_parameter_is_served(nodes, ros):
    nodes.start(label="arm")
    text = robot(LINKS, lambda i: i // 2)
    start = time.monotonic()
    result = ros.set_parameter("robot_description", text)
    print(f"tree ({len(text) / 1e6:.1f} MB) as the parameter: set in {time.monotonic() - start:.1f} s")
    assert result.successful, result.reason
    served(ros, LINKS, 90.0)
    print(f"tree: served {time.monotonic() - start:.1f} s after the set")
    check_gravity(ros, LINKS, lambda i: i // 2, "tree")


def test_fifty_megabyte_descriptions_on_the_topic(nodes, ros, latched):
    """A 50 MB comment in a one-link robot loads; then 50 MB of links is refused with the reason
    counted on /diagnostics, and the one-link robot stays."""
    node = nodes.start(label="arm")
    pub = latched(subscribed=True)
    comment = f'<robot name="commented">{link("only")}<!--{"x" * BIG}--></robot>'
    start = time.monotonic()
    pub.publish(String(data=comment))

    def loaded():
        r = ros.call(DescribeModel, DM, DescribeModel.Request())
        return r.success and "commented" in r.message

    assert ros.spin_until(loaded, 120.0), node.log()[-2000:]
    print(f"50 MB comment on the topic: loaded after {time.monotonic() - start:.1f} s")
    r = ros.call(DescribeModel, DM, DescribeModel.Request())
    assert list(r.link_names) == ["only"] and (r.nq, r.nv) == (0, 0), r
    text, n = many_links(BIG)
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    start = time.monotonic()
    pub.publish(String(data=text))

    def refused(m):
        values = sd.status_values(m, STATUS)
        return values is not None and sd.dropped_count(values, "/robot_description") > 0

    diag.wait(1, 120.0, refused)
    print(f"50 MB of links ({n}) on the topic: refused after {time.monotonic() - start:.1f} s")
    assert "more than 20000 links or joints" in node.log(), node.log()[-2000:]
    r = ros.call(DescribeModel, DM, DescribeModel.Request())
    assert "commented" in r.message, r.message
    node.assert_alive()


def test_a_fifty_megabyte_parameter_is_refused_with_the_reason(nodes, ros):
    node = nodes.start(label="arm")
    text, n = many_links(BIG)
    start = time.monotonic()
    result = ros.set_parameter("robot_description", text)
    print(f"50 MB of links ({n}) as the parameter: answered in {time.monotonic() - start:.1f} s")
    assert not result.successful
    assert "more than 20000 links or joints" in result.reason, result.reason[:500]
    assert len(result.reason) < 2000, f"reason of {len(result.reason)} characters"
    assert ros.get_parameters(["robot_description"]) == {"robot_description": ""}
    arm_still_served(ros)
    node.assert_alive()
