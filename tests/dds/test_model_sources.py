"""Where the model comes from: the `robot_description` parameter (here from a --params-file), the
`urdf_file` parameter, the latched `robot_description` topic (published before or after the node
starts; a new message reloads the model), else the embedded default; parameter files (`NODE:` and
`/**:` entries, `-p` overriding them) and start-up errors. One node per test.
"""

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from spatial_dynamics_msgs.srv import DescribeModel, InverseDynamics, MassMatrix
from std_msgs.msg import String

import sd_dds_support as sd
from sd_dds_support import assert_close

DM = "/spatial_dynamics/describe_model"
ID = "/spatial_dynamics/inverse_dynamics"


def describe(ros):
    r = ros.call(DescribeModel, DM, DescribeModel.Request())
    assert r.success, r.message
    return r


def wait_model(ros, predicate, timeout=sd.EVENT_S):
    last = [None]

    def check():
        last[0] = describe(ros)
        return predicate(last[0])

    assert ros.spin_until(check, timeout), f"model not as expected within {timeout} s: {last[0]}"
    return last[0]


def write_params(path, text):
    path.write_text(text)
    return path


def check_particle(ros):
    """Closed form for config/models/particle.urdf: tau = m qdd + [0, m g], m = 1, g = 9.81."""
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=["x", "z"], position=[0.3, -0.2], acceleration=[1.5, -0.5]))
    assert resp.success, resp.message
    assert_close(resp.effort, [1.5, -0.5 + 9.81], "particle ID")


# ---- robot_description parameter --------------------------------------------------------------


def test_robot_description_parameter_from_a_params_file_floating_anymal(nodes, ros, tmp_path):
    urdf = sd.anymal_urdf()
    text = urdf.read_text()
    params = write_params(
        tmp_path / "anymal.yaml",
        "spatial_dynamics:\n  ros__parameters:\n"
        f"    robot_description: {sd.yaml_string(text)}\n"
        "    floating_base: true\n",
    )
    nodes.start("--params-file", params, label="anymal")
    r = describe(ros)
    assert "robot_description parameter" in r.message
    assert r.floating_base and (r.nq, r.nv) == (19, 18)
    ref = sd.PinRef(urdf_text=text, floating=True)
    assert sorted(n for n, t in zip(r.joint_names, r.joint_types) if t != "floating") == sorted(ref.names)
    assert ros.get_parameters(["robot_description", "floating_base"]) == {"robot_description": text, "floating_base": True}
    names = list(reversed(ref.names))
    rng = np.random.default_rng(9)
    q = [float(x) for x in rng.uniform(-1, 1, len(names))]
    v = [float(x) for x in rng.standard_normal(len(names))]
    a = [float(x) for x in rng.standard_normal(len(names))]
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=names, position=q, velocity=v, acceleration=a))
    assert resp.success, resp.message
    zero6 = [0.0] * 6
    tau = ref.rnea(ref.q(names, q), ref.v(names, v, zero6), ref.v(names, a, zero6))
    assert_close(resp.effort, ref.pick(tau, names), "ANYmal joint efforts")
    bw = resp.base_wrench
    assert_close([bw.force.x, bw.force.y, bw.force.z, bw.torque.x, bw.torque.y, bw.torque.z], ref.pick_base(tau), "ANYmal base wrench")
    resp = ros.call(MassMatrix, "/spatial_dynamics/mass_matrix", MassMatrix.Request(name=names, position=q))
    assert resp.success, resp.message
    assert_close(np.array(resp.matrix).reshape(18, 18), ref.matrix(ref.crba(ref.q(names, q)), names), "ANYmal M")


# ---- urdf_file parameter ----------------------------------------------------------------------


def test_urdf_file_parameter(nodes, ros):
    nodes.start("-p", f"urdf_file:={sd.LAMP_URDF}", label="lamp")
    r = describe(ros)
    assert "lamp" in r.message and str(sd.LAMP_URDF) in r.message
    assert ros.get_parameters(["urdf_file"]) == {"urdf_file": str(sd.LAMP_URDF)}
    # The planar joint is described by the names requests take: one per coordinate.
    assert list(r.joint_names) == ["base/x", "base/y", "base/theta", "hinge1", "hinge2"]
    assert list(r.joint_types) == ["planar"] * 3 + ["revolute"] * 2
    assert (r.nq, r.nv) == (5, 5)
    assert list(r.position_lower) == [-math.inf] * 3 + [-2.5, -2.5] and list(r.position_upper) == [math.inf] * 3 + [2.5, 2.5]
    assert list(r.velocity_limit)[3:] == [10.0, 10.0] and list(r.effort_limit)[3:] == [20.0, 20.0]
    assert list(r.link_names) == sd.urdf_links(sd.LAMP_URDF)
    assert list(r.fused_links) == ["head"]


def test_describe_joint_without_limit_tag_has_infinite_velocity_and_effort_limits(nodes, ros):
    """DescribeModel.srv: velocity_limit / effort_limit are "+inf where the URDF gives none".
    lamp.urdf's planar joint `base` has no <limit> at all. Bug seen: both are reported as 0.0
    (a zero velocity/effort limit would tell a user the joint cannot move)."""
    nodes.start("-p", f"urdf_file:={sd.LAMP_URDF}", label="lamp_limits")
    r = describe(ros)
    assert list(r.joint_names[:3]) == ["base/x", "base/y", "base/theta"]
    for i in range(3):
        assert (r.position_lower[i], r.position_upper[i]) == (-math.inf, math.inf)
        assert (r.velocity_limit[i], r.effort_limit[i]) == (math.inf, math.inf), (
            f"{r.joint_names[i]}: velocity_limit {r.velocity_limit[i]}, effort_limit {r.effort_limit[i]}"
        )


@pytest.mark.parametrize("urdf", ["lamp", "default_arm", "mimic_gripper"])
def test_described_joint_names_are_the_names_requests_take(nodes, ros, urdf):
    """~/describe_model lists exactly the names the services accept: a request naming them all
    (in reverse order) succeeds and answers for each; the joint's own name of a planar joint is
    refused (its coordinates are named J/x, J/y, J/theta)."""
    path = {"lamp": sd.LAMP_URDF, "default_arm": sd.DEFAULT_ARM_URDF, "mimic_gripper": sd.MIMIC_GRIPPER_URDF}[urdf]
    nodes.start("-p", f"urdf_file:={path}", label=f"names_{urdf}")
    r = describe(ros)
    names = list(reversed(r.joint_names))
    assert len(names) == r.nv, (names, r.nv)
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=names, position=[0.1] * len(names)))
    assert resp.success, resp.message
    assert list(resp.name) == names
    if urdf == "lamp":
        resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=["base", "hinge1", "hinge2"], position=[0.0] * 3))
        assert not resp.success and "base" in resp.message, resp


# ---- robot_description topic ------------------------------------------------------------------


def test_robot_description_topic_published_before_the_node_starts(nodes, ros, latched):
    pub = latched()
    pub.publish(String(data=sd.PARTICLE_URDF.read_text()))
    ros.spin_for(0.1)
    nodes.start(label="before")
    r = wait_model(ros, lambda r: "particle" in r.message)
    assert "robot_description topic" in r.message
    assert list(r.joint_names) == ["x", "z"]
    check_particle(ros)


def test_robot_description_topic_after_start_and_reload(nodes, ros, latched):
    nodes.start(label="after")
    r = describe(ros)
    assert "sd_arm7" in r.message and "embedded default" in r.message
    pub = latched()
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, sd.EVENT_S)
    pub.publish(String(data=sd.MIMIC_GRIPPER_URDF.read_text()))
    r = wait_model(ros, lambda r: "mimic_gripper" in r.message)
    assert "robot_description topic" in r.message and list(r.joint_names) == ["wrist", "finger_left"]
    # A second description reloads the model.
    pub.publish(String(data=sd.PARTICLE_URDF.read_text()))
    r = wait_model(ros, lambda r: "particle" in r.message)
    assert "robot_description topic" in r.message
    check_particle(ros)


def test_parameter_wins_over_the_topic_and_clearing_it_falls_back_to_the_topic(nodes, ros, latched):
    nodes.start("-p", f"urdf_file:={sd.PARTICLE_URDF}", label="precedence")
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    pub = latched()
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, sd.EVENT_S)
    pub.publish(String(data=sd.MIMIC_GRIPPER_URDF.read_text()))
    # The description arrived (counted) but the urdf_file parameter keeps the particle.
    diag.wait(1, sd.EVENT_S, lambda m: int((sd.status_values(m, "spatial_dynamics: dynamics") or {}).get("/robot_description received", 0)) >= 1)
    r = describe(ros)
    assert "particle" in r.message and str(sd.PARTICLE_URDF) in r.message
    check_particle(ros)
    result = ros.set_parameter("urdf_file", "")
    assert result.successful, result.reason
    r = wait_model(ros, lambda r: "mimic_gripper" in r.message)
    assert "robot_description topic" in r.message


# ---- parameter files and -p -------------------------------------------------------------------


def test_params_file_by_node_name_and_wildcard_with_p_overriding(nodes, ros, tmp_path):
    params = write_params(
        tmp_path / "p.yaml",
        "/**:\n  ros__parameters:\n    method: crba\n    gravity: [0.0, 0.0, -1.62]\n"
        "spatial_dynamics:\n  ros__parameters:\n    locked_joints: ['joint7=0.25']\n    command_joints: [joint2, joint1]\n"
        "some_other_node:\n  ros__parameters:\n    floating_base: true\n",
    )
    nodes.start("--params-file", params, "-p", "gravity:=[0.0, 0.0, -3.71]", label="params")
    r = describe(ros)
    assert r.method == "crba"
    assert (r.gravity.x, r.gravity.y, r.gravity.z) == (0.0, 0.0, -3.71)
    assert r.floating_base is False
    assert [e.split("=")[0] for e in r.locked_joints] == ["joint7"] and float(r.locked_joints[0].split("=")[1]) == 0.25
    assert list(r.joint_names) == sd.ARM_JOINTS[:6]
    got = ros.get_parameters(["method", "gravity", "command_joints", "floating_base"])
    assert got["method"] == "crba" and list(got["gravity"]) == [0.0, 0.0, -3.71]
    assert list(got["command_joints"]) == ["joint2", "joint1"] and got["floating_base"] is False
    ref = sd.PinRef(sd.DEFAULT_ARM_URDF, gravity=[0.0, 0.0, -3.71], locked={"joint7": 0.25})
    q = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=sd.ARM_JOINTS[:6], position=q))
    assert resp.success, resp.message
    z = np.zeros(6)
    assert_close(resp.effort, ref.pick(ref.rnea(ref.q(sd.ARM_JOINTS[:6], q), z, z), sd.ARM_JOINTS[:6]), "ID with file parameters")


@pytest.mark.parametrize(
    "case",
    ["unknown_method", "bad_gravity", "missing_urdf_file", "unknown_locked_joint"],
)
def test_invalid_start_up_configuration_exits_non_zero_with_a_reason(nodes, tmp_path, case):
    args, word = {
        "unknown_method": (["-p", "method:=magic"], "magic"),
        "bad_gravity": (["-p", "gravity:=[1.0, 2.0]"], "gravity"),
        "missing_urdf_file": (["-p", "urdf_file:=/nonexistent/robot.urdf"], "/nonexistent/robot.urdf"),
        "unknown_locked_joint": (["-p", "locked_joints:=['elbow=0.1']"], "elbow"),
    }[case]
    node = nodes.start(*args, label=case, expect_exit=True)
    rc = node.wait_exit(10.0)
    assert rc not in (0, None), node.describe()
    assert word in node.log(), node.describe()
