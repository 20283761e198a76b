"""A floating-base robot: Solo12 from example-robot-data, loaded by the `urdf_file` parameter with
`floating_base: true` (given as -p arguments), against Pinocchio with a JointModelFreeFlyer root.

Conventions (InverseDynamics.srv / Pinocchio): base_pose = q[0:7] (position, quaternion x y z w),
base_twist = v[0:6] and base_accel = a[0:6] ([linear; angular], base frame), base_wrench = tau[0:6];
MassMatrix is (6+n) x (6+n), base first.
"""


import numpy as np
import pytest
from geometry_msgs.msg import Accel, Point, Pose, Quaternion, Twist, Vector3, Wrench
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics, LinkWrench
from spatial_dynamics_msgs.srv import DescribeModel, ForwardDynamics, InverseDynamics, MassMatrix
from std_msgs.msg import Float64MultiArray

import sd_dds_support as sd
from sd_dds_support import assert_close

ID = "/spatial_dynamics/inverse_dynamics"
FD = "/spatial_dynamics/forward_dynamics"
MM = "/spatial_dynamics/mass_matrix"
DM = "/spatial_dynamics/describe_model"


@pytest.fixture(scope="module")
def urdf():
    return sd.solo12_urdf()


@pytest.fixture(scope="module")
def solo(module_nodes, ros, urdf):
    node = module_nodes.start("-p", f"urdf_file:={urdf}", "-p", "floating_base:=true", label="solo12")
    ros.wait_for_service(DescribeModel, DM)
    return node


@pytest.fixture(scope="module")
def ref(urdf):
    return sd.PinRef(urdf, floating=True)


@pytest.fixture(scope="module")
def joints(urdf):
    return [j[0] for j in sd.urdf_joints(urdf)]


def vec3(x):
    return Vector3(x=float(x[0]), y=float(x[1]), z=float(x[2]))


def pose_msg(p):
    return Pose(position=Point(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(x=p[3], y=p[4], z=p[5], w=p[6]))


def six(msg_a, msg_b):
    return [msg_a.x, msg_a.y, msg_a.z, msg_b.x, msg_b.y, msg_b.z]


def random_base(rng):
    quat = rng.standard_normal(4)
    quat /= np.linalg.norm(quat)
    pose = [float(x) for x in np.concatenate([rng.uniform(-1, 1, 3), quat])]
    return pose, [float(x) for x in rng.standard_normal(6)], [float(x) for x in rng.standard_normal(6)]


def random_joint_state(rng, joints, urdf):
    names = list(joints)
    rng.shuffle(names)
    q = sd.random_positions(names, rng, urdf)
    return names, q, [float(x) for x in rng.standard_normal(len(names))], [float(x) for x in rng.standard_normal(len(names))]


def test_describe_floating_model(solo, ros, urdf, joints):
    r = ros.call(DescribeModel, DM, DescribeModel.Request())
    assert r.success, r.message
    assert r.floating_base is True
    assert (r.nq, r.nv) == (7 + 12, 6 + 12)
    by_name = {j[0]: j for j in sd.urdf_joints(urdf)}
    # The joints other than the base (the base itself is covered by the next test).
    listed = [i for i, t in enumerate(r.joint_types) if t != "floating"]
    assert [r.joint_names[i] for i in listed] == joints
    for i in listed:
        name = r.joint_names[i]
        _, kind, lo, hi, vel, eff = by_name[name]
        assert (r.joint_types[i], r.position_lower[i], r.position_upper[i], r.velocity_limit[i], r.effort_limit[i]) == (
            kind, lo, hi, vel, eff), name
    assert list(r.link_names) == sd.urdf_links(urdf)
    assert {"FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"} <= set(r.fused_links)


def test_describe_does_not_list_the_floating_base(solo, ros, joints):
    """DescribeModel.srv: "The floating base, if any, is not listed." joint_names is also the
    order the other services use when their `name` is empty, which never includes the base."""
    r = ros.call(DescribeModel, DM, DescribeModel.Request())
    assert r.success, r.message
    assert list(r.joint_names) == joints, f"joint_names {list(r.joint_names)} (types {list(r.joint_types)})"
    assert len(r.joint_types) == len(r.position_lower) == len(r.position_upper) == len(joints)
    assert len(r.velocity_limit) == len(r.effort_limit) == len(joints)
    assert "floating" not in r.joint_types
    # Consistent with the other services: an empty `name` answers exactly these joints.
    answer = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=[], position=[0.0] * len(joints)))
    assert answer.success, answer.message
    assert list(answer.name) == list(r.joint_names)


def test_inverse_dynamics_with_base_pose_twist_accel(solo, ros, ref, urdf, joints):
    rng = np.random.default_rng(101)
    for _ in range(5):
        pose, twist, accel = random_base(rng)
        names, q, v, a = random_joint_state(rng, joints, urdf)
        req = InverseDynamics.Request(name=names, position=q, velocity=v, acceleration=a)
        req.base_pose = pose_msg(pose)
        req.base_twist = Twist(linear=vec3(twist[:3]), angular=vec3(twist[3:]))
        req.base_accel = Accel(linear=vec3(accel[:3]), angular=vec3(accel[3:]))
        resp = ros.call(InverseDynamics, ID, req)
        assert resp.success, resp.message
        assert list(resp.name) == names
        tau = ref.rnea(ref.q(names, q, pose), ref.v(names, v, twist), ref.v(names, a, accel))
        assert_close(resp.effort, ref.pick(tau, names), "joint efforts")
        assert_close(six(resp.base_wrench.force, resp.base_wrench.torque), ref.pick_base(tau), "base wrench")


def test_inverse_dynamics_default_base_fields(solo, ros, ref, urdf, joints):
    """Default Pose (identity orientation), zero twist and accel."""
    rng = np.random.default_rng(7)
    names, q, v, a = random_joint_state(rng, joints, urdf)
    resp = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=names, position=q))
    assert resp.success, resp.message
    zero = ref.v([], [], [0.0] * 6)
    tau = ref.rnea(ref.q(names, q, [0, 0, 0, 0, 0, 0, 1]), zero, zero)
    assert_close(resp.effort, ref.pick(tau, names), "joint efforts")
    assert_close(six(resp.base_wrench.force, resp.base_wrench.torque), ref.pick_base(tau), "base wrench")


@pytest.mark.parametrize("method", ["", "aba", "crba", "rnea_columns"])
def test_forward_dynamics_with_base(solo, ros, ref, urdf, joints, method):
    rng = np.random.default_rng(202)
    for _ in range(3):
        pose, twist, base_wrench = random_base(rng)
        names, q, v, tau = random_joint_state(rng, joints, urdf)
        req = ForwardDynamics.Request(name=names, position=q, velocity=v, effort=tau, method=method)
        req.base_pose = pose_msg(pose)
        req.base_twist = Twist(linear=vec3(twist[:3]), angular=vec3(twist[3:]))
        req.base_wrench = Wrench(force=vec3(base_wrench[:3]), torque=vec3(base_wrench[3:]))
        resp = ros.call(ForwardDynamics, FD, req)
        assert resp.success, resp.message
        assert list(resp.name) == names
        acc = ref.aba(ref.q(names, q, pose), ref.v(names, v, twist), ref.v(names, tau, base_wrench))
        assert_close(resp.acceleration, ref.pick(acc, names), f"joint accelerations [{method}]")
        assert_close(six(resp.base_accel.linear, resp.base_accel.angular), ref.pick_base(acc), f"base accel [{method}]")


def test_mass_matrix_base_first(solo, ros, ref, urdf, joints):
    rng = np.random.default_rng(303)
    for _ in range(3):
        pose, _, _ = random_base(rng)
        names, q, _, _ = random_joint_state(rng, joints, urdf)
        resp = ros.call(MassMatrix, MM, MassMatrix.Request(name=names, position=q, base_pose=pose_msg(pose)))
        assert resp.success, resp.message
        assert list(resp.name) == names
        n = 6 + len(names)
        assert len(resp.matrix) == n * n
        assert_close(np.array(resp.matrix).reshape(n, n), ref.matrix(ref.crba(ref.q(names, q, pose)), names), "M")


def test_external_wrench_on_a_fused_foot(solo, ros, ref, urdf, joints):
    rng = np.random.default_rng(404)
    pose, twist, accel = random_base(rng)
    names, q, v, a = random_joint_state(rng, joints, urdf)
    wrenches = [("FL_FOOT", "world", [0.0, 0.0, 30.0], [0.0, 0.0, 0.0]), ("HR_LOWER_LEG", "", [1.0, -2.0, 0.5], [0.1, 0.0, -0.2])]
    req = InverseDynamics.Request(name=names, position=q, velocity=v, acceleration=a)
    req.base_pose = pose_msg(pose)
    req.base_twist = Twist(linear=vec3(twist[:3]), angular=vec3(twist[3:]))
    req.base_accel = Accel(linear=vec3(accel[:3]), angular=vec3(accel[3:]))
    req.external_wrenches = [
        LinkWrench(link=l, frame=f, wrench=Wrench(force=vec3(fo), torque=vec3(to))) for l, f, fo, to in wrenches
    ]
    resp = ros.call(InverseDynamics, ID, req)
    assert resp.success, resp.message
    pq = ref.q(names, q, pose)
    tau = ref.rnea(pq, ref.v(names, v, twist), ref.v(names, a, accel), ref.fext(pq, wrenches))
    assert_close(resp.effort, ref.pick(tau, names), "joint efforts with contact")
    assert_close(six(resp.base_wrench.force, resp.base_wrench.torque), ref.pick_base(tau), "base wrench with contact")


BAD_BASE = {
    "zero_quaternion": (dict(base_pose=Pose(orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=0.0))), "base_pose"),
    "nan_position": (dict(base_pose=Pose(position=Point(x=float("nan")))), "base_pose"),
    "inf_twist": (dict(base_twist=Twist(angular=Vector3(y=float("inf")))), "base_twist"),
    "nan_accel": (dict(base_accel=Accel(linear=Vector3(z=float("nan")))), "base_accel"),
}


@pytest.mark.parametrize("case", list(BAD_BASE))
def test_bad_base_fields_are_refused(solo, ros, ref, joints, case):
    fields, word = BAD_BASE[case]
    req = InverseDynamics.Request(name=joints, position=[0.0] * len(joints), **fields)
    resp = ros.call(InverseDynamics, ID, req)
    assert resp.success is False and word in resp.message, resp
    good = ros.call(InverseDynamics, ID, InverseDynamics.Request(name=joints, position=[0.1] * len(joints)))
    assert good.success, good.message


@pytest.fixture(scope="module")
def topic_case(solo, ros, ref, urdf, joints):
    """A base state, a joint state and a command for the topic tests, with the expected values."""
    rng = np.random.default_rng(505)
    pose, twist, _ = random_base(rng)
    names, q, v, _ = random_joint_state(rng, joints, urdf)
    command = {n: float(x) for n, x in zip(joints, rng.standard_normal(len(joints)))}
    odom = Odometry()
    odom.pose.pose = pose_msg(pose)
    odom.twist.twist = Twist(linear=vec3(twist[:3]), angular=vec3(twist[3:]))
    pq = ref.q(names, q, pose)
    case = dict(
        names=names, q=q, v=v, command=command, odom=odom, ref=ref, pq=pq, twist=twist,
        want_g=ref.pick(ref.gravity(pq), names),
    )
    case["gravity_out"] = ros.collector(JointState, "/spatial_dynamics/gravity_effort")
    case["accel_out"] = ros.collector(JointDynamics, "/spatial_dynamics/acceleration")
    case["gravity_out"].wait_publisher()
    case["accel_out"].wait_publisher()
    case["odom_pub"] = ros.publisher(Odometry, "/spatial_dynamics/base_state", sd.qos_best_effort(10))
    case["js_pub"] = ros.publisher(JointState, "/joint_states", sd.qos_reliable(10))
    return case


def _close(got, want):
    return np.linalg.norm(np.asarray(got) - want) <= sd.REL_TOL * max(1.0, np.linalg.norm(want))


def _joint_states_sender(ros, c, stamps, before=()):
    def publish():
        for f in before:  # repeated every round: a fresh writer's first samples can be lost
            f()
        ros.spin_for(0.05)
        stamp = sd.fresh_stamp()
        stamps.append(stamp)
        msg = JointState(name=c["names"], position=c["q"], velocity=c["v"])
        msg.header.stamp = stamp
        c["js_pub"].publish(msg)

    return publish


def test_base_state_topic_sets_the_base_for_gravity_effort(ros, topic_case):
    """~/base_state (nav_msgs/Odometry: pose in world) sets the base pose used for joint_states:
    the gravity torque of the joints depends on the base orientation."""
    c = topic_case
    stamps = []
    publish = _joint_states_sender(ros, c, stamps, before=[lambda: c["odom_pub"].publish(c["odom"])])
    got = ros.exchange(
        publish, c["gravity_out"],
        lambda m: any(sd.stamp_eq(m.header.stamp, s) for s in stamps) and _close(m.effort, c["want_g"]),
        timeout=sd.EVENT_S,
    )
    assert list(got.name) == c["names"]
    assert_close(got.effort, c["want_g"], "gravity effort at the base pose")
    assert_close(got.position, c["q"], "position echo")


def _check_command_drives_joints_only(ros, c, command, send_command):
    ref = c["ref"]
    # A free-floating base is unactuated: the command drives the joints only (base part 0).
    want_a = ref.pick(ref.aba(c["pq"], ref.v(c["names"], c["v"], c["twist"]), ref.v(list(command), list(command.values()), [0.0] * 6)), c["names"])
    stamps = []
    publish = _joint_states_sender(ros, c, stamps, before=[lambda: c["odom_pub"].publish(c["odom"]), send_command])
    want_effort = [command[n] for n in c["names"]]
    # Wait until the base state and the command are both in effect (gravity at the base pose,
    # the command echoed in `effort`), then compare the acceleration of that same message.
    acc = ros.exchange(
        publish, c["accel_out"],
        lambda m: any(sd.stamp_eq(m.header.stamp, s) for s in stamps[1:]) and list(m.effort) == want_effort
        and any(sd.stamp_eq(g.header.stamp, m.header.stamp) and _close(g.effort, c["want_g"]) for g in c["gravity_out"].messages),
        timeout=sd.EVENT_S,
    )
    assert list(acc.name) == c["names"]
    assert_close(acc.velocity, c["v"], "velocity echo")
    assert_close(acc.acceleration, want_a, "acceleration: joints driven by the command, base unactuated, base twist from ~/base_state")


def test_effort_command_on_a_floating_base_drives_only_the_joints(ros, topic_case):
    """~/effort_command names joints only: the base's generalized force must be zero. Bug seen:
    the base part is whatever the node computed last (the gravity base wrench of the previous
    joint_states message), so ~/acceleration is that of a pushed base."""
    c = topic_case
    command = c["command"]
    effort_pub = ros.publisher(JointState, "/spatial_dynamics/effort_command", sd.qos_reliable(10))
    cmd = JointState(name=list(command), effort=list(command.values()))
    _check_command_drives_joints_only(ros, c, command, lambda: effort_pub.publish(cmd))


def test_commands_array_on_a_floating_base_drives_only_the_joints(ros, topic_case, joints):
    c = topic_case
    command = {n: -0.5 * x + 0.125 for n, x in c["command"].items()}  # not the other test's command
    commands_pub = ros.publisher(Float64MultiArray, "/spatial_dynamics/commands", sd.qos_reliable(10))
    msg = Float64MultiArray(data=[command[n] for n in joints])  # command_joints default: model order
    _check_command_drives_joints_only(ros, c, command, lambda: commands_pub.publish(msg))
