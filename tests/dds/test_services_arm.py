"""The four services on the default robot (embedded sd_arm7) against Pinocchio on
config/models/default_arm.urdf, and every kind of bad request (each followed by a good one).

One node serves the whole module: no test here changes its state.
"""

import math

import numpy as np
import pytest
from geometry_msgs.msg import Vector3, Wrench
from spatial_dynamics_msgs.msg import LinkWrench
from spatial_dynamics_msgs.srv import DescribeModel, ForwardDynamics, InverseDynamics, MassMatrix

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, DEFAULT_ARM_URDF, assert_close

ID = "/spatial_dynamics/inverse_dynamics"
FD = "/spatial_dynamics/forward_dynamics"
MM = "/spatial_dynamics/mass_matrix"
DM = "/spatial_dynamics/describe_model"


def shuffled(rng):
    names = list(ARM_JOINTS)
    rng.shuffle(names)
    return names


def state(rng, names):
    q = sd.random_positions(names, rng, DEFAULT_ARM_URDF)
    v, a = (list(map(float, rng.standard_normal(len(names)))) for _ in range(2))
    return q, v, a


def wrench_msg(link, frame, force, torque):
    return LinkWrench(
        link=link,
        frame=frame,
        wrench=Wrench(force=Vector3(x=force[0], y=force[1], z=force[2]), torque=Vector3(x=torque[0], y=torque[1], z=torque[2])),
    )


def id_call(ros, names, q, v=(), a=(), wrenches=()):
    req = InverseDynamics.Request(name=list(names), position=list(q), velocity=list(v), acceleration=list(a))
    req.external_wrenches = [wrench_msg(*w) for w in wrenches]
    return ros.call(InverseDynamics, ID, req)


def good_call_still_works(ros, ref):
    """After a bad request, the node answers a good one correctly."""
    q = [0.1, -0.2, 0.3, -0.4, 0.5, -0.6, 0.7]
    resp = id_call(ros, ARM_JOINTS, q)
    assert resp.success, resp.message
    assert_close(resp.effort, ref.pick(ref.rnea(ref.q(ARM_JOINTS, q), ref.v([], []), ref.v([], [])), ARM_JOINTS), "ID after a bad request")


# ---- DescribeModel ----------------------------------------------------------------------------


def test_describe_model_matches_the_urdf(arm, ros):
    r = ros.call(DescribeModel, DM, DescribeModel.Request())
    assert r.success, r.message
    assert "sd_arm7" in r.message
    joints = sd.urdf_joints(DEFAULT_ARM_URDF)
    assert list(r.joint_names) == [j[0] for j in joints] == ARM_JOINTS
    assert list(r.joint_types) == [j[1] for j in joints]
    assert r.joint_types[6] == "continuous"
    assert list(r.position_lower) == [j[2] for j in joints]
    assert list(r.position_upper) == [j[3] for j in joints]
    assert r.position_lower[6] == -math.inf and r.position_upper[6] == math.inf
    assert list(r.velocity_limit) == [j[4] for j in joints]
    assert list(r.effort_limit) == [j[5] for j in joints]
    assert list(r.link_names) == sd.urdf_links(DEFAULT_ARM_URDF)
    assert (r.nq, r.nv) == (7, 7)
    assert r.floating_base is False
    assert (r.gravity.x, r.gravity.y, r.gravity.z) == (0.0, 0.0, -9.81)
    # method "auto": the cheapest accurate method (FLOPs) on this model, with the measurements in the message.
    assert r.method in ("aba", "crba", "rnea_columns")
    assert f"method auto: {r.method} (measured: aba " in r.message, r.message
    assert list(r.locked_joints) == []
    assert sorted(r.fused_links) == ["base_link", "flange", "tool0"]


# ---- InverseDynamics --------------------------------------------------------------------------


def test_inverse_dynamics_matches_pinocchio_in_any_joint_order(arm, ros, ref):
    rng = np.random.default_rng(11)
    for _ in range(8):
        names = shuffled(rng)
        q, v, a = state(rng, names)
        resp = id_call(ros, names, q, v, a)
        assert resp.success, resp.message
        assert list(resp.name) == names
        want = ref.rnea(ref.q(names, q), ref.v(names, v), ref.v(names, a))
        assert_close(resp.effort, ref.pick(want, names), f"ID at q={q}")
        w = resp.base_wrench
        assert [w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z] == [0.0] * 6


def test_inverse_dynamics_empty_name_is_model_order_and_empty_arrays_are_zero(arm, ros, ref):
    q = [0.3, -0.7, 0.5, 1.1, -0.4, 0.9, 2.2]
    resp = id_call(ros, [], q)
    assert resp.success, resp.message
    assert list(resp.name) == ARM_JOINTS
    zero = np.zeros(7)
    assert_close(resp.effort, ref.pick(ref.rnea(ref.q(ARM_JOINTS, q), zero, zero), ARM_JOINTS), "ID v=a=0")
    # ... and it is the gravity torque (Pinocchio's computeGeneralizedGravity).
    assert_close(resp.effort, ref.pick(ref.gravity(ref.q(ARM_JOINTS, q)), ARM_JOINTS), "ID = g(q)")


def test_continuous_joint_angle_wraps(arm, ros, ref):
    """joint7 is continuous: angle t and t + 2 pi give the same answer (Pinocchio: cos, sin)."""
    q = [0.2, 0.4, -0.3, -1.0, 0.6, 0.8, 1.3]
    v = [0.1] * 7
    a = [0.2] * 7
    first = id_call(ros, ARM_JOINTS, q, v, a)
    second = id_call(ros, ARM_JOINTS, q[:6] + [q[6] + 2 * math.pi], v, a)
    assert first.success and second.success, (first.message, second.message)
    want = ref.pick(ref.rnea(ref.q(ARM_JOINTS, q), ref.v(ARM_JOINTS, v), ref.v(ARM_JOINTS, a)), ARM_JOINTS)
    assert_close(first.effort, want, "ID at t")
    assert_close(second.effort, want, "ID at t + 2 pi", tol=1e-8)


# ---- ForwardDynamics --------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["", "aba", "crba", "rnea_columns"])
def test_forward_dynamics_matches_pinocchio(arm, ros, ref, method):
    rng = np.random.default_rng(23)
    for _ in range(5):
        names = shuffled(rng)
        q, v, tau = state(rng, names)
        req = ForwardDynamics.Request(name=names, position=q, velocity=v, effort=tau, method=method)
        resp = ros.call(ForwardDynamics, FD, req)
        assert resp.success, resp.message
        assert list(resp.name) == names
        want = ref.aba(ref.q(names, q), ref.v(names, v), ref.v(names, tau))
        assert_close(resp.acceleration, ref.pick(want, names), f"FD[{method}] at q={q}")
        b = resp.base_accel
        assert [b.linear.x, b.linear.y, b.linear.z, b.angular.x, b.angular.y, b.angular.z] == [0.0] * 6


def test_forward_dynamics_empty_velocity_and_effort_are_zero(arm, ros, ref):
    q = [-0.5, 0.9, 1.2, -1.4, 0.3, 1.1, -2.0]
    resp = ros.call(ForwardDynamics, FD, ForwardDynamics.Request(name=[], position=q))
    assert resp.success, resp.message
    assert list(resp.name) == ARM_JOINTS
    zero = np.zeros(7)
    assert_close(resp.acceleration, ref.pick(ref.aba(ref.q(ARM_JOINTS, q), zero, zero), ARM_JOINTS), "free fall")


# ---- MassMatrix -------------------------------------------------------------------------------


def test_mass_matrix_matches_pinocchio_in_request_order(arm, ros, ref):
    rng = np.random.default_rng(5)
    for _ in range(5):
        names = shuffled(rng)
        q = sd.random_positions(names, rng, DEFAULT_ARM_URDF)
        resp = ros.call(MassMatrix, MM, MassMatrix.Request(name=names, position=q))
        assert resp.success, resp.message
        assert list(resp.name) == names
        got = np.array(resp.matrix).reshape(7, 7)
        assert_close(got, ref.matrix(ref.crba(ref.q(names, q)), names), f"M at q={q}")
    by_name = dict(zip(names, q))
    q_model = [by_name[n] for n in ARM_JOINTS]
    resp = ros.call(MassMatrix, MM, MassMatrix.Request(name=[], position=q_model))
    assert resp.success and list(resp.name) == ARM_JOINTS
    assert_close(np.array(resp.matrix).reshape(7, 7), ref.matrix(ref.crba(ref.q(ARM_JOINTS, q_model)), ARM_JOINTS), "M model order")


# ---- External wrenches ------------------------------------------------------------------------

WRENCH_CASES = {
    "link7_own_frame_empty": [("link7", "", [1.0, -2.0, 3.0], [0.1, 0.2, -0.3])],
    "link7_own_frame_named": [("link7", "link7", [1.0, -2.0, 3.0], [0.1, 0.2, -0.3])],
    "tool0_fused_massless": [("tool0", "tool0", [0.0, 5.0, -1.0], [0.0, 0.0, 0.4])],
    "flange_fused_world": [("flange", "world", [0.0, 0.0, -20.0], [0.0, 0.0, 0.0])],
    "link3_world": [("link3", "world", [4.0, 1.0, -2.0], [0.5, -0.5, 0.25])],
    "several": [
        ("link2", "", [1.0, 0.0, 0.0], [0.0, 0.3, 0.0]),
        ("tool0", "world", [0.0, 0.0, -9.81], [0.0, 0.0, 0.0]),
        ("link5", "world", [0.0, 2.0, 0.0], [0.1, 0.0, 0.0]),
    ],
}


@pytest.mark.parametrize("case", sorted(WRENCH_CASES))
def test_external_wrenches_inverse_dynamics(arm, ros, ref, case):
    wrenches = WRENCH_CASES[case]
    rng = np.random.default_rng(31)
    names = shuffled(rng)
    q, v, a = state(rng, names)
    resp = id_call(ros, names, q, v, a, wrenches)
    assert resp.success, resp.message
    pq = ref.q(names, q)
    want = ref.rnea(pq, ref.v(names, v), ref.v(names, a), ref.fext(pq, wrenches))
    assert_close(resp.effort, ref.pick(want, names), f"ID with {wrenches}")
    without = ref.pick(ref.rnea(pq, ref.v(names, v), ref.v(names, a)), names)
    assert np.linalg.norm(np.array(resp.effort) - without) > 1e-3, "the wrench must change the effort"


@pytest.mark.parametrize("case", ["link7_own_frame_empty", "flange_fused_world", "several"])
def test_external_wrenches_forward_dynamics(arm, ros, ref, case):
    wrenches = WRENCH_CASES[case]
    rng = np.random.default_rng(37)
    names = shuffled(rng)
    q, v, tau = state(rng, names)
    req = ForwardDynamics.Request(name=names, position=q, velocity=v, effort=tau)
    req.external_wrenches = [wrench_msg(*w) for w in wrenches]
    resp = ros.call(ForwardDynamics, FD, req)
    assert resp.success, resp.message
    pq = ref.q(names, q)
    want = ref.aba(pq, ref.v(names, v), ref.v(names, tau), ref.fext(pq, wrenches))
    assert_close(resp.acceleration, ref.pick(want, names), f"FD with {wrenches}")


def test_wrench_on_links_fixed_to_the_world_has_no_effect(arm, ros, ref):
    q = [0.3, -0.7, 0.5, 1.1, -0.4, 0.9, 0.2]
    plain = id_call(ros, ARM_JOINTS, q)
    pushed = id_call(ros, ARM_JOINTS, q, wrenches=[("base_link", "", [10.0, 0, 0], [0, 0, 1.0]), ("world", "world", [0, 5.0, 0], [0, 0, 0])])
    assert plain.success and pushed.success, (plain.message, pushed.message)
    assert_close(pushed.effort, plain.effort, "wrench on base_link / world")


# ---- Bad requests -----------------------------------------------------------------------------

Q0 = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]
NAN, INF = float("nan"), float("inf")


def _with(values, i, x):
    out = list(values)
    out[i] = x
    return out


# (service, request fields, words the message must contain)
BAD_REQUESTS = {
    "id_omitted_joint": (ID, dict(name=ARM_JOINTS[:6], position=Q0[:6]), ["joint7"]),
    "id_unknown_joint": (ID, dict(name=ARM_JOINTS + ["elbow"], position=Q0 + [0.0]), ["elbow"]),
    "id_duplicate_joint": (ID, dict(name=ARM_JOINTS + ["joint3"], position=Q0 + [0.3]), ["joint3"]),
    "id_position_too_short": (ID, dict(name=ARM_JOINTS, position=Q0[:5]), ["position"]),
    "id_position_empty": (ID, dict(name=ARM_JOINTS, position=[]), ["position"]),
    "id_velocity_wrong_length": (ID, dict(name=ARM_JOINTS, position=Q0, velocity=[0.0] * 3), ["velocity"]),
    "id_acceleration_wrong_length": (ID, dict(name=ARM_JOINTS, position=Q0, acceleration=[0.0] * 8), ["acceleration"]),
    "id_nan_position": (ID, dict(name=ARM_JOINTS, position=_with(Q0, 3, NAN)), ["position", "joint4"]),
    "id_inf_velocity": (ID, dict(name=ARM_JOINTS, position=Q0, velocity=_with([0.0] * 7, 1, INF)), ["velocity", "joint2"]),
    "id_neg_inf_acceleration": (ID, dict(name=ARM_JOINTS, position=Q0, acceleration=_with([0.0] * 7, 6, -INF)), ["acceleration", "joint7"]),
    "id_unknown_link_wrench": (ID, dict(name=ARM_JOINTS, position=Q0, external_wrenches=[("gripper_pad", "", [1, 0, 0], [0, 0, 0])]), ["gripper_pad"]),
    "id_bad_wrench_frame": (ID, dict(name=ARM_JOINTS, position=Q0, external_wrenches=[("link7", "elbow_frame", [1, 0, 0], [0, 0, 0])]), ["elbow_frame"]),
    "id_nan_wrench": (ID, dict(name=ARM_JOINTS, position=Q0, external_wrenches=[("link4", "", [NAN, 0, 0], [0, 0, 0])]), ["link4"]),
    "fd_unknown_method": (FD, dict(name=ARM_JOINTS, position=Q0, method="magic"), ["magic"]),
    "fd_omitted_joint": (FD, dict(name=ARM_JOINTS[1:], position=Q0[1:]), ["joint1"]),
    "fd_unknown_joint": (FD, dict(name=["joint0"] + ARM_JOINTS, position=[0.0] + Q0), ["joint0"]),
    "fd_duplicate_joint": (FD, dict(name=ARM_JOINTS + ["joint7"], position=Q0 + [0.7]), ["joint7"]),
    "fd_effort_wrong_length": (FD, dict(name=ARM_JOINTS, position=Q0, effort=[1.0] * 6), ["effort"]),
    "fd_nan_effort": (FD, dict(name=ARM_JOINTS, position=Q0, effort=_with([0.0] * 7, 4, NAN)), ["effort", "joint5"]),
    "fd_unknown_link_wrench": (FD, dict(name=ARM_JOINTS, position=Q0, external_wrenches=[("link99", "world", [1, 0, 0], [0, 0, 0])]), ["link99"]),
    "mm_omitted_joint": (MM, dict(name=["joint1", "joint2"], position=[0.0, 0.0]), ["joint3"]),
    "mm_unknown_joint": (MM, dict(name=ARM_JOINTS + ["wrist"], position=Q0 + [0.0]), ["wrist"]),
    "mm_duplicate_joint": (MM, dict(name=ARM_JOINTS + ["joint1"], position=Q0 + [0.0]), ["joint1"]),
    "mm_position_wrong_length": (MM, dict(name=ARM_JOINTS, position=Q0 + [0.0]), ["position"]),
    "mm_inf_position": (MM, dict(name=ARM_JOINTS, position=_with(Q0, 0, -INF)), ["position", "joint1"]),
}
SERVICE_TYPES = {ID: InverseDynamics, FD: ForwardDynamics, MM: MassMatrix}
RESULT_ARRAYS = {ID: ("name", "effort"), FD: ("name", "acceleration"), MM: ("name", "matrix")}


@pytest.mark.parametrize("case", list(BAD_REQUESTS))
def test_bad_request_is_refused_with_a_reason_then_the_node_keeps_serving(arm, ros, ref, case):
    service, fields, words = BAD_REQUESTS[case]
    srv = SERVICE_TYPES[service]
    fields = dict(fields)
    wrenches = fields.pop("external_wrenches", [])
    req = srv.Request(**fields)
    if wrenches:
        req.external_wrenches = [wrench_msg(*w) for w in wrenches]
    resp = ros.call(srv, service, req)
    assert resp.success is False, f"{case}: accepted: {resp}"
    assert resp.message, f"{case}: no reason given"
    for word in words:
        assert word in resp.message, f"{case}: the reason {resp.message!r} does not name {word!r}"
    for array in RESULT_ARRAYS[service]:
        assert len(getattr(resp, array)) == 0, f"{case}: {array} not empty on failure: {resp}"
    good_call_still_works(ros, ref)


def test_names_of_fixed_joints_are_accepted_and_ignored(arm, ros, ref):
    """joint_map.rs (name rules, services and topics alike): "names of joints without a
    coordinate (mimic followers, fixed and locked joints) are accepted and ignored". A
    /joint_states source that also reports fixed joints must be usable. Bug seen: a fixed joint's
    name is refused as "unknown joint 'flange_joint' in name"."""
    names = ["world_to_base"] + ARM_JOINTS + ["flange_joint", "tool_joint"]
    resp = id_call(ros, names, [0.0] + Q0 + [0.0, 0.0])
    assert resp.success, resp.message
    assert list(resp.name) == ARM_JOINTS
    zero = np.zeros(7)
    assert_close(resp.effort, ref.pick(ref.rnea(ref.q(ARM_JOINTS, Q0), zero, zero), ARM_JOINTS), "ID, fixed joints named")
