"""Big robot descriptions reaching the node: a 10 000-link chain on the latched robot_description
topic and a 10 000-link tree as the robot_description parameter are loaded and served (answers
checked against Pinocchio on the same text); 50 MB descriptions (a huge comment: loads; 170 000
links: refused, naming the limit) on the topic and as a parameter leave the node alive and
serving, the old model kept when the new one is refused. Times are printed (pytest -s).
"""

import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from spatial_dynamics_msgs.srv import DescribeModel, InverseDynamics
from std_msgs.msg import String

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

DM = "/spatial_dynamics/describe_model"
ID = "/spatial_dynamics/inverse_dynamics"
STATUS = "/spatial_dynamics: dynamics"
BIG = 50 << 20
LINKS = 10_000


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
    """Polls ~/inverse_dynamics (empty names: model order, zero state) until the node answers for
    a model of `n` coordinates; returns the response and the seconds it took."""
    start = time.monotonic()
    last = None
    while time.monotonic() - start < timeout:
        last = ros.call(InverseDynamics, ID, InverseDynamics.Request(position=[0.0] * n), timeout=30.0)
        if last.success and len(last.name) == n:
            return last, time.monotonic() - start
        ros.spin_for(0.5)
    raise AssertionError(f"not serving a {n}-coordinate model within {timeout} s; last answer: {str(last)[:300]}")


def check_against_pinocchio(ros, text, label):
    ref = sd.PinRef(urdf_text=text)
    rng = np.random.default_rng(1)
    names = ref.names
    q = [float(x) for x in rng.uniform(-0.5, 0.5, len(names))]
    v = [float(x) for x in rng.uniform(-0.01, 0.01, len(names))]
    start = time.monotonic()
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=names, position=q, velocity=v), timeout=30.0)
    print(f"{label}: ID with {len(names)} named joints answered in {time.monotonic() - start:.2f} s")
    assert resp.success, resp.message
    want = ref.rnea(ref.q(names, q), ref.v(names, v), np.zeros(len(names)))
    assert_close(resp.effort, ref.pick(want, names), f"{label}: ID")


def arm_still_served(ros):
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=ARM_JOINTS, position=[0.1] * 7))
    assert resp.success and list(resp.name) == ARM_JOINTS, resp.message


@pytest.fixture
def latched(ros):
    pubs = []

    def make():
        pub = ros.node.create_publisher(String, "/robot_description", sd.QOS_LATCHED)
        pubs.append(pub)
        assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 10.0), "robot_description not subscribed"
        return pub

    yield make
    for pub in pubs:
        ros.node.destroy_publisher(pub)


def test_ten_thousand_link_chain_on_the_topic_is_served(nodes, ros, latched):
    nodes.start(label="arm")
    text = robot(LINKS, lambda i: i - 1)
    start = time.monotonic()
    latched().publish(String(data=text))
    _, took = served(ros, LINKS, 90.0)
    print(f"chain ({len(text) / 1e6:.1f} MB) on the topic: served after {time.monotonic() - start:.1f} s")
    check_against_pinocchio(ros, text, "chain")


def test_ten_thousand_link_tree_as_the_parameter_is_served(nodes, ros):
    nodes.start(label="arm")
    text = robot(LINKS, lambda i: i // 2)
    start = time.monotonic()
    result = ros.set_parameter("robot_description", text)
    print(f"tree ({len(text) / 1e6:.1f} MB) as the parameter: set in {time.monotonic() - start:.1f} s")
    assert result.successful, result.reason
    served(ros, LINKS, 90.0)
    print(f"tree: served {time.monotonic() - start:.1f} s after the set")
    check_against_pinocchio(ros, text, "tree")


def test_fifty_megabyte_descriptions_on_the_topic(nodes, ros, latched):
    """A 50 MB comment in a one-link robot loads; then 50 MB of links is refused with the reason
    counted on /diagnostics, and the one-link robot stays."""
    node = nodes.start(label="arm")
    pub = latched()
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
