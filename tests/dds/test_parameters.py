"""Parameters through the standard rcl_interfaces services: list, get, describe, set; invalid values
refused with a reason (the old value stays and the node keeps serving); valid values take effect
at once. Every test that changes a parameter restores it (one node serves the module).
"""


import numpy as np
import pytest
from geometry_msgs.msg import Vector3, Wrench
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics, LinkWrench
from spatial_dynamics_msgs.srv import DescribeModel, ForwardDynamics, InverseDynamics, MassMatrix
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, DEFAULT_ARM_URDF, assert_close

T = Parameter.Type
ID = "/spatial_dynamics/inverse_dynamics"
FD = "/spatial_dynamics/forward_dynamics"
DM = "/spatial_dynamics/describe_model"
NAMES = ["robot_description", "urdf_file", "floating_base", "ignore_mimic", "locked_joints", "root_link", "tip_links",
         "prune_massless", "gravity", "method", "command_joints"]
DEFAULTS = {
    "robot_description": "",
    "urdf_file": "",
    "floating_base": False,
    "ignore_mimic": False,
    "locked_joints": [],
    "root_link": "",
    "tip_links": [],
    "prune_massless": False,
    "gravity": [0.0, 0.0, -9.81],
    "method": "auto",
    "command_joints": [],
}
TYPES = {
    "robot_description": T.STRING,
    "urdf_file": T.STRING,
    "floating_base": T.BOOL,
    "ignore_mimic": T.BOOL,
    "locked_joints": T.STRING_ARRAY,
    "root_link": T.STRING,
    "tip_links": T.STRING_ARRAY,
    "prune_massless": T.BOOL,
    "gravity": T.DOUBLE_ARRAY,
    "method": T.STRING,
    "command_joints": T.STRING_ARRAY,
}
Q = [0.3, -0.7, 0.5, 1.1, -0.4, 0.9, 0.2]
FD_METHODS = ("aba", "crba", "rnea_columns")


@pytest.fixture
def restore(arm, ros):
    """Sets every parameter back to its default after the test (and checks that it worked)."""
    yield
    results = ros.set_parameters([Parameter(n, TYPES[n], DEFAULTS[n]) for n in NAMES])
    assert all(r.successful for r in results), results
    wait_model(ros, lambda r: "sd_arm7" in r.message and list(r.joint_names) == ARM_JOINTS and not r.floating_base
               and r.method in FD_METHODS and "method auto: " in r.message and (r.gravity.x, r.gravity.y, r.gravity.z) == (0.0, 0.0, -9.81))


def describe(ros):
    r = ros.call(DescribeModel, DM, DescribeModel.Request())
    assert r.success, r.message
    return r


def normalise(v):
    return list(v) if not isinstance(v, (str, bool, int, float)) and v is not None else v


def parse_locks(entries):
    return {e.split("=")[0]: float(e.split("=")[1]) for e in entries}


def set_ok(ros, name, value):
    result = ros.set_parameter(name, value, TYPES[name])
    assert result.successful, f"set {name}={value!r} refused: {result.reason}"


def wait_model(ros, predicate, timeout=sd.EVENT_S):
    """Parameter changes take effect in the node's loop: poll DescribeModel briefly."""
    last = [None]

    def check():
        last[0] = describe(ros)
        return predicate(last[0])

    assert ros.spin_until(check, timeout), f"model not changed within {timeout} s: {last[0]}"
    return last[0]


def id_ok(ros, names, q, v=(), a=()):
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=list(names), position=list(q), velocity=list(v), acceleration=list(a)))
    assert resp.success, resp.message
    return resp


# ---- list / get / describe --------------------------------------------------------------------


def test_list_parameters(arm, ros):
    assert set(NAMES) <= set(ros.list_parameters())


def test_get_parameters_defaults(arm, ros):
    got = ros.get_parameters(NAMES)
    assert {k: normalise(v) for k, v in got.items()} == DEFAULTS


def test_describe_parameters_and_types(arm, ros):
    descriptors = ros.describe_parameters(NAMES)
    assert {n: descriptors[n].type for n in NAMES} == {n: TYPES[n].value for n in NAMES}
    assert ros.get_parameter_types(NAMES) == {n: TYPES[n].value for n in NAMES}


# ---- invalid values ---------------------------------------------------------------------------

INVALID = {
    "gravity_two_numbers": ("gravity", T.DOUBLE_ARRAY, [1.0, 2.0]),
    "gravity_four_numbers": ("gravity", T.DOUBLE_ARRAY, [1.0, 2.0, 3.0, 4.0]),
    "gravity_nan": ("gravity", T.DOUBLE_ARRAY, [float("nan"), 0.0, -9.81]),
    "gravity_string": ("gravity", T.STRING, "down"),
    "method_unknown": ("method", T.STRING, "magic"),
    "method_integer": ("method", T.INTEGER, 3),
    "floating_base_string": ("floating_base", T.STRING, "yes"),
    "ignore_mimic_integer": ("ignore_mimic", T.INTEGER, 1),
    "locked_joints_no_position": ("locked_joints", T.STRING_ARRAY, ["joint7"]),
    "locked_joints_bad_number": ("locked_joints", T.STRING_ARRAY, ["joint7=abc"]),
    "locked_joints_unknown_joint": ("locked_joints", T.STRING_ARRAY, ["elbow=0.1"]),
    "root_link_unknown": ("root_link", T.STRING, "elbow_link"),
    "tip_links_unknown": ("tip_links", T.STRING_ARRAY, ["link4", "gripper"]),
    "tip_links_string": ("tip_links", T.STRING, "link4"),
    "prune_massless_string": ("prune_massless", T.STRING, "yes"),
    "command_joints_unknown": ("command_joints", T.STRING_ARRAY, ["joint1", "elbow"]),
    "urdf_file_missing": ("urdf_file", T.STRING, "/nonexistent/robot.urdf"),
    "robot_description_not_urdf": ("robot_description", T.STRING, "<robot name='broken'><link"),
    "undeclared_parameter": ("nonsense", T.DOUBLE, 1.0),
}


@pytest.mark.parametrize("case", list(INVALID))
def test_invalid_value_is_refused_and_the_old_value_stays(arm, ros, ref, case):
    name, type_, value = INVALID[case]
    before = ros.get_parameters(NAMES)
    result = ros.set_parameter(name, value, type_)
    assert result.successful is False, f"{case}: accepted"
    assert result.reason, f"{case}: no reason given"
    after = ros.get_parameters(NAMES)
    assert {k: normalise(v) for k, v in after.items()} == {k: normalise(v) for k, v in before.items()} == DEFAULTS
    r = describe(ros)
    assert "sd_arm7" in r.message and list(r.joint_names) == ARM_JOINTS and r.method in FD_METHODS
    zero = np.zeros(7)
    resp = id_ok(ros, ARM_JOINTS, Q)
    assert_close(resp.effort, ref.pick(ref.rnea(ref.q(ARM_JOINTS, Q), zero, zero), ARM_JOINTS), "ID after a refused value")


def test_one_invalid_value_in_a_batch_does_not_block_the_valid_ones(arm, ros, restore):
    results = ros.set_parameters([Parameter("method", T.STRING, "crba"), Parameter("gravity", T.DOUBLE_ARRAY, [0.0, 0.0])])
    assert [r.successful for r in results] == [True, False], results
    got = ros.get_parameters(["method", "gravity"])
    assert got["method"] == "crba" and normalise(got["gravity"]) == [0.0, 0.0, -9.81], got
    wait_model(ros, lambda r: r.method == "crba")


def set_atomically(ros, params, node=sd.NODE):
    """Sets params (rclpy Parameters) through set_parameters_atomically; returns its result."""
    from rcl_interfaces.srv import SetParametersAtomically

    request = SetParametersAtomically.Request(parameters=[p.to_parameter_msg() for p in params])
    return ros.call(SetParametersAtomically, f"{node}/set_parameters_atomically", request).result


def test_an_atomic_set_is_validated_as_a_whole(arm, ros):
    particle = sd.PARTICLE_URDF.read_text()
    # Valid together only: the particle's joint as the command joint (unknown to the arm).
    result = set_atomically(ros, [Parameter("robot_description", T.STRING, particle),
                                  Parameter("command_joints", T.STRING_ARRAY, ["z"])])
    assert result.successful, result.reason
    wait_model(ros, lambda r: "particle" in r.message)
    assert ros.get_parameters(["command_joints"])["command_joints"] == ["z"]
    # A urdf_file the robot_description shadows is the source once that is emptied: checked.
    result = ros.set_parameter("urdf_file", "/nonexistent/robot.urdf", T.STRING)
    assert not result.successful and "urdf_file" in result.reason, result
    # Back to the arm: valid together only (the arm has no joint 'z').
    assert not ros.set_parameter("robot_description", "", T.STRING).successful
    result = set_atomically(ros, [Parameter("robot_description", T.STRING, ""),
                                  Parameter("command_joints", T.STRING_ARRAY, [])])
    assert result.successful, result.reason
    wait_model(ros, lambda r: "sd_arm7" in r.message and list(r.joint_names) == ARM_JOINTS)
    # Valid one by one, not together: the particle has no link4. Nothing changes.
    result = set_atomically(ros, [Parameter("tip_links", T.STRING_ARRAY, ["link4"]),
                                  Parameter("robot_description", T.STRING, particle)])
    assert not result.successful and "link4" in result.reason, result
    assert {k: normalise(v) for k, v in ros.get_parameters(NAMES).items()} == DEFAULTS
    assert "sd_arm7" in describe(ros).message


# ---- valid values take effect -----------------------------------------------------------------


def test_gravity_takes_effect_in_services_topics_and_describe(arm, ros, restore):
    set_ok(ros, "gravity", [0.0, 0.0, 0.0])
    assert normalise(ros.get_parameters(["gravity"])["gravity"]) == [0.0, 0.0, 0.0]
    r = wait_model(ros, lambda r: (r.gravity.x, r.gravity.y, r.gravity.z) == (0.0, 0.0, 0.0))
    assert list(r.joint_names) == ARM_JOINTS
    resp = id_ok(ros, ARM_JOINTS, Q)
    assert list(resp.effort) == [0.0] * 7
    # ~/gravity_effort becomes zero.
    out = ros.collector(JointState, "/spatial_dynamics/gravity_effort")
    out.wait_publisher()
    pub = ros.publisher(JointState, "/joint_states", sd.qos_reliable(10))
    sent = []

    def publish():
        m = JointState(name=ARM_JOINTS, position=Q)
        m.header.stamp = sd.fresh_stamp()
        sent.append(m)
        pub.publish(m)

    got = ros.exchange(publish, out, lambda m: any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent))
    assert list(got.effort) == [0.0] * 7
    # Any other gravity vector: against Pinocchio with that gravity.
    g = [1.5, -2.0, -3.0]
    set_ok(ros, "gravity", g)
    wait_model(ros, lambda r: [r.gravity.x, r.gravity.y, r.gravity.z] == g)
    ref_g = sd.PinRef(DEFAULT_ARM_URDF, gravity=g)
    v, a = [0.1 * i for i in range(7)], [-0.2 * i for i in range(7)]
    resp = id_ok(ros, ARM_JOINTS, Q, v, a)
    assert_close(resp.effort, ref_g.pick(ref_g.rnea(ref_g.q(ARM_JOINTS, Q), ref_g.v(ARM_JOINTS, v), ref_g.v(ARM_JOINTS, a)), ARM_JOINTS), "ID with gravity g")


def test_method_takes_effect(arm, ros, ref, restore):
    for method in ("crba", "rnea_columns", "aba"):
        set_ok(ros, "method", method)
        assert ros.get_parameters(["method"])["method"] == method
        wait_model(ros, lambda r: r.method == method)
        tau = [1.0, -1.0, 0.5, 0.0, 2.0, -0.5, 0.25]
        resp = ros.call(ForwardDynamics, FD, ForwardDynamics.Request(name=ARM_JOINTS, position=Q, effort=tau))
        assert resp.success, resp.message
        want = ref.aba(ref.q(ARM_JOINTS, Q), ref.v([], []), ref.v(ARM_JOINTS, tau))
        assert_close(resp.acceleration, ref.pick(want, ARM_JOINTS), f"FD with default method {method}")


@pytest.mark.parametrize("locked", [{"joint7": 0.5}, {"joint2": -0.3, "joint5": 1.0}])
def test_locked_joints_take_effect(arm, ros, restore, locked):
    entries = [f"{n}={v}" for n, v in locked.items()]
    set_ok(ros, "locked_joints", entries)
    # Read back as NAME=POSITION (the number may be written differently: 1.0 or 1).
    assert parse_locks(ros.get_parameters(["locked_joints"])["locked_joints"]) == locked
    free = [n for n in ARM_JOINTS if n not in locked]
    r = wait_model(ros, lambda r: list(r.joint_names) == free)
    assert parse_locks(r.locked_joints) == locked
    assert (r.nq, r.nv) == (len(free), len(free))
    if "joint7" in locked:
        assert {"link7", "flange", "tool0"} <= set(r.fused_links)
    ref_l = sd.PinRef(DEFAULT_ARM_URDF, locked=locked)
    assert ref_l.names == free
    q = [0.2 * (i + 1) * (-1) ** i for i in range(len(free))]
    v = [0.3] * len(free)
    a = [-0.1 * i for i in range(len(free))]
    want = ref_l.pick(ref_l.rnea(ref_l.q(free, q), ref_l.v(free, v), ref_l.v(free, a)), free)
    resp = id_ok(ros, free, q, v, a)
    assert list(resp.name) == free
    assert_close(resp.effort, want, f"ID with {entries} locked")
    # A locked joint's name may still be given (e.g. in /joint_states): it is ignored.
    names = list(reversed(ARM_JOINTS))
    pos = {**dict(zip(free, q)), **{n: 123.0 for n in locked}}
    vel = {**dict(zip(free, v)), **{n: 9.0 for n in locked}}
    acc = {**dict(zip(free, a)), **{n: 9.0 for n in locked}}
    resp = id_ok(ros, names, [pos[n] for n in names], [vel[n] for n in names], [acc[n] for n in names])
    assert list(resp.name) == [n for n in names if n in free]
    assert_close(resp.effort, ref_l.pick(ref_l.rnea(ref_l.q(free, q), ref_l.v(free, v), ref_l.v(free, a)), list(resp.name)), "locked names ignored")
    # External wrenches on links fused by the lock (their frames include the locked joint's turn).
    wrenches = [("tool0", "", [1.0, 2.0, -3.0], [0.2, -0.1, 0.3]), ("link7", "world", [0.0, 4.0, -9.0], [0.0, 0.5, 0.0]),
                ("link5", "link5", [-2.0, 0.0, 1.0], [0.0, 0.0, 0.7])]
    req = InverseDynamics.Request(name=free, position=q, velocity=v, acceleration=a)
    req.external_wrenches = [
        LinkWrench(link=l, frame=f, wrench=Wrench(force=Vector3(x=fo[0], y=fo[1], z=fo[2]), torque=Vector3(x=to[0], y=to[1], z=to[2])))
        for l, f, fo, to in wrenches
    ]
    resp = ros.call(InverseDynamics, ID, req)
    assert resp.success, resp.message
    pq = ref_l.q(free, q)
    want = ref_l.rnea(pq, ref_l.v(free, v), ref_l.v(free, a), ref_l.fext(pq, wrenches))
    assert_close(resp.effort, ref_l.pick(want, free), f"ID with wrenches, {entries} locked")


def test_root_and_tip_links_take_effect(arm, ros, restore):
    # Keep joint2..joint4 (root link1, tip link4): joint1 freezes at zero (link1 becomes the
    # fixed base), joint5..joint7 freeze and their links lump onto link4. Pinocchio's reduced
    # model with those joints locked at zero is the independent reference.
    set_ok(ros, "root_link", "link1")
    set_ok(ros, "tip_links", ["link4"])
    kept = ["joint2", "joint3", "joint4"]
    r = wait_model(ros, lambda r: list(r.joint_names) == kept)
    assert parse_locks(r.locked_joints) == {n: 0.0 for n in ["joint1", "joint5", "joint6", "joint7"]}
    assert "root: 'link1'" in r.message and "tips: link4" in r.message, r.message
    ref_r = sd.PinRef(DEFAULT_ARM_URDF, locked={n: 0.0 for n in ["joint1", "joint5", "joint6", "joint7"]})
    assert ref_r.names == kept
    q, v, a = [0.4, -0.3, 0.8], [0.5, -0.2, 0.1], [1.0, 0.3, -0.7]
    want = ref_r.pick(ref_r.rnea(ref_r.q(kept, q), ref_r.v(kept, v), ref_r.v(kept, a)), kept)
    assert_close(id_ok(ros, kept, q, v, a).effort, want, "ID of the root/tip-reduced arm")
    # The frozen joints' names (as /joint_states carries them) are accepted and ignored.
    names = ARM_JOINTS
    pos = {**dict(zip(kept, q)), **{n: 5.0 for n in names if n not in kept}}
    vel = {**dict(zip(kept, v)), **{n: 5.0 for n in names if n not in kept}}
    acc = {**dict(zip(kept, a)), **{n: 5.0 for n in names if n not in kept}}
    resp = id_ok(ros, names, [pos[n] for n in names], [vel[n] for n in names], [acc[n] for n in names])
    assert list(resp.name) == kept
    assert_close(resp.effort, want, "frozen names ignored")


def test_floating_base_takes_effect(arm, ros, restore):
    set_ok(ros, "floating_base", True)
    r = wait_model(ros, lambda r: r.floating_base)
    assert (r.nq, r.nv) == (14, 13)
    ref_f = sd.PinRef(DEFAULT_ARM_URDF, floating=True)
    resp = ros.call(MassMatrix, "/spatial_dynamics/mass_matrix", MassMatrix.Request(name=ARM_JOINTS, position=Q))
    assert resp.success, resp.message
    assert_close(np.array(resp.matrix).reshape(13, 13), ref_f.matrix(ref_f.crba(ref_f.q(ARM_JOINTS, Q)), ARM_JOINTS), "M with a floating base")


def test_urdf_file_and_ignore_mimic_take_effect(arm, ros, restore):
    set_ok(ros, "urdf_file", str(sd.MIMIC_GRIPPER_URDF))
    r = wait_model(ros, lambda r: "mimic_gripper" in r.message)
    assert list(r.joint_names) == ["wrist", "finger_left"]
    assert str(sd.MIMIC_GRIPPER_URDF) in r.message
    # Mimic followers (finger_right, thumb) may be named: they are accepted and ignored.
    resp = id_ok(ros, ["thumb", "finger_left", "finger_right", "wrist"], [5.0, 0.02, 5.0, 0.3], [9.0, 0.1, 9.0, -0.5], [9.0, 0.3, 9.0, 1.5])
    assert list(resp.name) == ["finger_left", "wrist"]
    # Mimic honoured: the constrained system, as Pinocchio's native mimic model (mimic=True).
    ref_n = sd.PinRef(sd.MIMIC_GRIPPER_URDF, mimic=True)
    names = ["finger_left", "wrist"]
    want = ref_n.rnea(ref_n.q(names, [0.02, 0.3]), ref_n.v(names, [0.1, -0.5]), ref_n.v(names, [0.3, 1.5]))
    assert_close(resp.effort, ref_n.pick(want, names), "ID with mimic joints")
    set_ok(ros, "ignore_mimic", True)
    r = wait_model(ros, lambda r: len(r.joint_names) == 4)
    assert sorted(r.joint_names) == ["finger_left", "finger_right", "thumb", "wrist"]
    # With mimic ignored the model is Pinocchio's default reading of the URDF.
    ref_m = sd.PinRef(sd.MIMIC_GRIPPER_URDF)
    names = ["thumb", "finger_right", "wrist", "finger_left"]
    q, v, a = [0.2, 0.01, -0.4, 0.03], [0.5, -0.1, 0.3, 0.2], [1.0, 0.2, -0.5, 0.1]
    resp = id_ok(ros, names, q, v, a)
    assert_close(resp.effort, ref_m.pick(ref_m.rnea(ref_m.q(names, q), ref_m.v(names, v), ref_m.v(names, a)), names), "ID mimic ignored")


def test_robot_description_parameter_takes_effect(arm, ros, restore):
    set_ok(ros, "robot_description", sd.PARTICLE_URDF.read_text())
    r = wait_model(ros, lambda r: "particle" in r.message)
    assert list(r.joint_names) == ["x", "z"] and "robot_description parameter" in r.message
    resp = id_ok(ros, ["z", "x"], [0.5, -1.0], [], [2.0, -3.0])
    m, g = 1.0, 9.81
    assert_close(resp.effort, [m * 2.0 + m * g, m * -3.0], "particle tau = m qdd + [0, m g]")


def test_command_joints_take_effect(arm, ros, ref, restore):
    order = ["joint3", "joint1", "joint6"]
    set_ok(ros, "command_joints", order)
    assert normalise(ros.get_parameters(["command_joints"])["command_joints"]) == order
    ros.spin_for(0.1)
    accel = ros.collector(JointDynamics, "/spatial_dynamics/acceleration")
    ffc = ros.collector(Float64MultiArray, "/spatial_dynamics/feedforward_commands")
    accel.wait_publisher()
    ffc.wait_publisher()
    commands = ros.publisher(Float64MultiArray, "/spatial_dynamics/commands", sd.qos_reliable(10))
    js = ros.publisher(JointState, "/joint_states", sd.qos_reliable(10))
    reference = ros.publisher(JointTrajectory, "/spatial_dynamics/reference", sd.qos_reliable(10))
    data = [2.0, -1.0, 0.5]  # joint3, joint1, joint6; the others get zero
    command = {n: 0.0 for n in ARM_JOINTS}
    command.update(zip(order, data))
    sent = []

    def publish():
        commands.publish(Float64MultiArray(data=data))
        ros.spin_for(0.02)
        m = JointState(name=ARM_JOINTS, position=Q)
        m.header.stamp = sd.fresh_stamp()
        sent.append(m)
        js.publish(m)

    want_effort = [command[n] for n in ARM_JOINTS]
    got = ros.exchange(publish, accel, lambda m: any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent) and list(m.effort) == want_effort)
    want = ref.aba(ref.q(ARM_JOINTS, Q), ref.v([], []), ref.v(ARM_JOINTS, want_effort))
    assert_close(got.acceleration, ref.pick(want, ARM_JOINTS), "acceleration under command_joints")
    # ~/feedforward_commands follows command_joints too.
    v, a = [0.1] * 7, [0.2] * 7
    tau = ref.rnea(ref.q(ARM_JOINTS, Q), ref.v(ARM_JOINTS, v), ref.v(ARM_JOINTS, a))
    want_ffc = ref.pick(tau, order)

    def publish_reference():
        t = JointTrajectory(joint_names=ARM_JOINTS, points=[JointTrajectoryPoint(positions=Q, velocities=v, accelerations=a)])
        t.header.stamp = sd.fresh_stamp()
        reference.publish(t)

    got = ros.exchange(publish_reference, ffc, lambda m: len(m.data) == 3 and np.allclose(m.data, want_ffc, atol=1e-6))
    assert_close(got.data, want_ffc, "feedforward_commands in command_joints order")
