"""Bad topic inputs: each one is dropped (no output for it), counted on /diagnostics under
"<topic> dropped: <reason kind>", and the node keeps working (a good input right after is
answered correctly; a bad command leaves the previous good command in effect).
"""

import os
import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics
from spatial_dynamics_msgs.srv import DescribeModel, InverseDynamics
from std_msgs.msg import Float64MultiArray, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

STATUS = "spatial_dynamics: dynamics"
JS = "/joint_states"
EFFORT = "/spatial_dynamics/effort_command"
COMMANDS = "/spatial_dynamics/commands"
REFERENCE = "/spatial_dynamics/reference"
BASE = "/spatial_dynamics/base_state"
DESCRIPTION = "/robot_description"
Q = [0.4, -0.6, 0.3, 1.2, -0.5, 0.8, -2.5]
NAN, INF = float("nan"), float("inf")
MILLION = 1_000_000
GOOD_COMMAND = dict(zip(ARM_JOINTS, [1.5, -2.0, 0.5, 3.0, -0.25, 0.75, 0.1]))


@pytest.fixture(scope="module")
def io(module_nodes, ros, ref):
    module_nodes.start(label="arm")
    ros.wait_for_service(DescribeModel, "/spatial_dynamics/describe_model")
    c = {
        "gravity": ros.collector(JointState, "/spatial_dynamics/gravity_effort"),
        "accel": ros.collector(JointDynamics, "/spatial_dynamics/acceleration"),
        "ff": ros.collector(JointState, "/spatial_dynamics/feedforward_effort"),
        "diag": ros.collector(DiagnosticArray, "/diagnostics"),
    }
    for col in c.values():
        col.wait_publisher()
    c[JS] = ros.publisher(JointState, JS, sd.qos_reliable(10))
    c[EFFORT] = ros.publisher(JointState, EFFORT, sd.qos_reliable(10))
    c[COMMANDS] = ros.publisher(Float64MultiArray, COMMANDS, sd.qos_reliable(10))
    c[REFERENCE] = ros.publisher(JointTrajectory, REFERENCE, sd.qos_reliable(10))
    c[BASE] = ros.publisher(Odometry, BASE, sd.qos_best_effort(10))
    # Prime every reliable input with a good message whose effect is seen, so that a bad message
    # later is not lost to discovery: the good command echoes in ~/acceleration, the good
    # reference gives ~/feedforward_effort.
    command = JointState(name=ARM_JOINTS, effort=[GOOD_COMMAND[n] for n in ARM_JOINTS])
    good_command_in_effect(ros, c, ref, extra=lambda: c[EFFORT].publish(command))
    good_command_in_effect(ros, c, ref, extra=lambda: c[COMMANDS].publish(Float64MultiArray(data=[GOOD_COMMAND[n] for n in ARM_JOINTS])))
    good_reference_answered(ros, c, ref)
    return c


def js(names=ARM_JOINTS, q=Q, v=()):
    msg = JointState(name=list(names), position=list(q), velocity=list(v))
    msg.header.stamp = sd.fresh_stamp()
    return msg


def traj(names=ARM_JOINTS, points=None):
    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp = sd.fresh_stamp()
    msg.points = points if points is not None else [JointTrajectoryPoint(positions=list(Q))]
    return msg


def answered(ros, c, output, publish_msg, make, accept=None, timeout=sd.EVENT_S):
    sent = []

    def publish():
        msg = make()
        sent.append(msg)
        publish_msg(msg)

    return ros.exchange(
        publish, c[output],
        lambda m: any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent) and (accept is None or accept(m)),
        timeout=timeout,
    )


def good_command_in_effect(ros, c, ref, extra=None):
    """A good joint state is answered, with GOOD_COMMAND in effect, and the values are right."""

    def publish(msg):
        if extra:
            extra()
            ros.spin_for(0.02)
        c[JS].publish(msg)

    want_effort = [GOOD_COMMAND[n] for n in ARM_JOINTS]
    got = answered(ros, c, "accel", publish, js, accept=lambda m: list(m.effort) == want_effort)
    tau = ref.v(ARM_JOINTS, want_effort)
    assert_close(got.acceleration, ref.pick(ref.aba(ref.q(ARM_JOINTS, Q), ref.v([], []), tau), ARM_JOINTS), "acceleration")
    g = c["gravity"].wait(1, sd.EVENT_S, lambda m: sd.stamp_eq(m.header.stamp, got.header.stamp))[0]
    assert_close(g.effort, ref.pick(ref.gravity(ref.q(ARM_JOINTS, Q)), ARM_JOINTS), "gravity effort")


def good_reference_answered(ros, c, ref):
    got = answered(ros, c, "ff", c[REFERENCE].publish, traj)
    zero = ref.v([], [])
    assert_close(got.effort, ref.pick(ref.rnea(ref.q(ARM_JOINTS, Q), zero, zero), ARM_JOINTS), "feedforward effort")


def latest_report(ros, c, timeout=sd.EVENT_S):
    c["diag"].wait(1, timeout, lambda m: sd.status_values(m, STATUS) is not None)
    return sd.status_values(c["diag"].matching(lambda m: sd.status_values(m, STATUS) is not None)[-1], STATUS)


def expect_dropped(ros, c, topic, word, send_bad, resend=False, timeout=sd.EVENT_S):
    """Sends a bad message (for best-effort topics, again after every /diagnostics report that
    has not counted it yet) until /diagnostics counts one more drop on `topic` of a kind
    containing `word`; returns the report's values."""
    before = latest_report(ros, c)
    received_before = int(before.get(f"{topic} received", 0))
    end = time.monotonic() + timeout
    send_bad()
    while True:
        c["diag"].clear()
        values = latest_report(ros, c)
        # Only the expected kind: a huge best-effort message of an earlier test, sent again and
        # again, may still arrive and be counted under its own kind.
        increased = {
            k: int(v) - int(before.get(k, 0))
            for k, v in values.items()
            if k.startswith(f"{topic} dropped: ") and word in k[len(f"{topic} dropped: "):] and int(v) > int(before.get(k, 0))
        }
        if increased:
            break
        assert time.monotonic() < end, f"no drop counted on {topic} within {timeout} s; /diagnostics: {values}"
        if resend:
            send_bad()
    if not resend:
        assert sum(increased.values()) == 1, increased
    assert int(values[f"{topic} received"]) > received_before
    status = next(s for s in c["diag"].messages[-1].status if s.name == STATUS)
    assert sd.level(status) == 1 and "dropped" in status.message, status
    return values


# ---- joint_states -----------------------------------------------------------------------------

BAD_JOINT_STATES = {
    "unknown_joint": (lambda: js(ARM_JOINTS + ["elbow"], Q + [0.0]), "unknown joint"),
    "omitted_joint": (lambda: js(ARM_JOINTS[:6], Q[:6]), "lacks"),
    "duplicate_joint": (lambda: js(ARM_JOINTS + ["joint2"], Q + [0.0]), "joint"),
    "position_wrong_length": (lambda: js(ARM_JOINTS, Q[:6]), "position"),
    "position_empty": (lambda: js(ARM_JOINTS, []), "position"),
    "velocity_wrong_length": (lambda: js(ARM_JOINTS, Q, [0.0] * 3), "velocity"),
    "nan_position": (lambda: js(ARM_JOINTS, Q[:2] + [NAN] + Q[3:]), "position"),
    "inf_velocity": (lambda: js(ARM_JOINTS, Q, [0.0] * 6 + [INF]), "velocity"),
    "empty_message": (lambda: js([], [], []), "position"),
    "million_unknown_names": (lambda: js([f"j{i}" for i in range(MILLION)], [0.0] * MILLION), "unknown joint"),
    "million_positions": (lambda: js(ARM_JOINTS, [0.0] * MILLION), "position"),
    "million_duplicates": (lambda: js(ARM_JOINTS + ["joint1"] * MILLION, [0.0] * (MILLION + 7)), "joint"),
}


@pytest.mark.parametrize("case", list(BAD_JOINT_STATES))
def test_bad_joint_states_dropped_and_counted(ros, io, ref, case):
    make, word = BAD_JOINT_STATES[case]
    bad = make()  # built once: a million-entry message takes a while to build on a busy machine

    # joint_states is best effort: a message of 10+ MB (a million names) travels in hundreds of
    # UDP fragments and is lost whole if one is (more often so while the machine is busy); it is
    # sent again after every report that has not counted it, for as long as it takes.
    expect_dropped(ros, io, JS, word, lambda: io[JS].publish(bad), resend=True,
                   timeout=3 * sd.EVENT_S if case.startswith("million") else sd.EVENT_S)
    # A good joint state answered after the bad one: an answer to the bad one would have come
    # before it (one writer per output, in order).
    good_command_in_effect(ros, io, ref)
    for out in ("gravity", "accel"):
        leaked = [m for m in io[out].messages if sd.stamp_eq(m.header.stamp, bad.header.stamp)]
        assert not leaked, f"{out} answered a bad joint state: {leaked[0]}"


# ---- ~/effort_command and ~/commands ----------------------------------------------------------

BAD_COMMANDS = {
    "effort_unknown_joint": (EFFORT, lambda: JointState(name=ARM_JOINTS + ["gripper"], effort=[9.0] * 8), "unknown joint"),
    "effort_omitted_joint": (EFFORT, lambda: JointState(name=ARM_JOINTS[:5], effort=[9.0] * 5), "lacks"),
    "effort_duplicate_joint": (EFFORT, lambda: JointState(name=ARM_JOINTS + ["joint1"], effort=[9.0] * 8), "joint"),
    "effort_wrong_length": (EFFORT, lambda: JointState(name=ARM_JOINTS, effort=[9.0] * 6), "effort"),
    "effort_empty": (EFFORT, lambda: JointState(name=ARM_JOINTS, effort=[]), "effort"),
    "effort_nan": (EFFORT, lambda: JointState(name=ARM_JOINTS, effort=[9.0] * 3 + [NAN] + [9.0] * 3), "effort"),
    "commands_wrong_length": (COMMANDS, lambda: Float64MultiArray(data=[9.0] * 6), "commands"),
    "commands_too_long": (COMMANDS, lambda: Float64MultiArray(data=[9.0] * 8), "commands"),
    "commands_inf": (COMMANDS, lambda: Float64MultiArray(data=[9.0] * 6 + [-INF]), "commands"),
    "effort_empty_message": (EFFORT, lambda: JointState(), "effort"),
    "commands_empty_message": (COMMANDS, lambda: Float64MultiArray(), "commands"),
    "effort_million_values": (EFFORT, lambda: JointState(name=ARM_JOINTS, effort=[9.0] * MILLION), "effort"),
    "commands_million_values": (COMMANDS, lambda: Float64MultiArray(data=[9.0] * MILLION), "commands"),
}


@pytest.mark.parametrize("case", list(BAD_COMMANDS))
def test_bad_command_dropped_counted_and_previous_command_kept(ros, io, ref, case):
    topic, make, word = BAD_COMMANDS[case]
    expect_dropped(ros, io, topic, word, lambda: io[topic].publish(make()))
    good_command_in_effect(ros, io, ref)  # GOOD_COMMAND is still the one in effect


# ---- ~/reference ------------------------------------------------------------------------------

BAD_REFERENCES = {
    "no_points": (lambda: traj(points=[]), "no points"),
    "unknown_joint": (lambda: traj(ARM_JOINTS + ["elbow"], [JointTrajectoryPoint(positions=Q + [0.0])]), "unknown joint"),
    "omitted_joint": (lambda: traj(ARM_JOINTS[1:], [JointTrajectoryPoint(positions=Q[1:])]), "lacks"),
    "positions_wrong_length": (lambda: traj(points=[JointTrajectoryPoint(positions=Q[:4])]), "position"),
    "nan_acceleration": (lambda: traj(points=[JointTrajectoryPoint(positions=Q, accelerations=[0.0] * 6 + [NAN])]), "points"),
    "empty_message": (lambda: traj([], []), "no points"),
    "million_names": (lambda: traj([f"j{i}" for i in range(MILLION)], [JointTrajectoryPoint(positions=[0.0] * MILLION)]), "unknown joint"),
}


@pytest.mark.parametrize("case", list(BAD_REFERENCES))
def test_bad_reference_dropped_and_counted(ros, io, ref, case):
    make, word = BAD_REFERENCES[case]
    sent = []

    def send():
        msg = make()
        sent.append(msg)
        io[REFERENCE].publish(msg)

    expect_dropped(ros, io, REFERENCE, word, send)
    leaked = [m for m in io["ff"].messages if any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent)]
    assert not leaked, f"feedforward_effort answered a bad reference: {leaked[0]}"
    good_reference_answered(ros, io, ref)


# ---- ~/base_state and robot_description -------------------------------------------------------


def test_base_state_on_a_fixed_base_model_is_dropped(ros, io, ref):
    odom = Odometry()
    odom.pose.pose.orientation.w = 1.0
    expect_dropped(ros, io, BASE, "floating base", lambda: io[BASE].publish(odom), resend=True)
    good_command_in_effect(ros, io, ref)


def test_unusable_robot_description_keeps_the_model(ros, io, ref):
    pub = ros.node.create_publisher(String, DESCRIPTION, sd.QOS_LATCHED)
    try:
        assert ros.spin_until(lambda: pub.get_subscription_count() > 0, sd.EVENT_S), "robot_description not subscribed"
        expect_dropped(ros, io, DESCRIPTION, "robot description", lambda: pub.publish(String(data="<robot name='broken'><link")))
        r = ros.call(DescribeModel, "/spatial_dynamics/describe_model", DescribeModel.Request())
        assert r.success and "sd_arm7" in r.message and list(r.joint_names) == ARM_JOINTS, r
        good_command_in_effect(ros, io, ref)
    finally:
        ros.node.destroy_publisher(pub)


def test_services_still_answer_after_all_bad_inputs(ros, io, ref):
    resp = ros.call(InverseDynamics, "/spatial_dynamics/inverse_dynamics", InverseDynamics.Request(name=ARM_JOINTS, position=Q))
    assert resp.success, resp.message
    zero = ref.v([], [])
    assert_close(resp.effort, ref.pick(ref.rnea(ref.q(ARM_JOINTS, Q), zero, zero), ARM_JOINTS), "ID")


# ---- a flood of bad input ---------------------------------------------------------------------


def test_a_flood_of_bad_joint_states_is_counted_warned_about_once_a_second_and_others_are_served(ros, io, ref, module_nodes):
    """One publisher floods /joint_states with bad messages for 3 s; meanwhile another client (its
    own rclpy context: another DDS participant) gets right gravity answers to its good joint
    states and right service answers. Every bad message that arrives is counted; the log warns
    at most once a second, saying how many more were dropped in between."""
    node = module_nodes.started[0]
    other = sd.RosSession(int(os.environ["ROS_DOMAIN_ID"]), "dds_test_other_client")
    try:
        other_js = other.publisher(JointState, JS, sd.qos_reliable(10))
        other_gravity = other.collector(JointState, "/spatial_dynamics/gravity_effort")
        other_gravity.wait_publisher()
        before = latest_report(ros, io)
        warned_before = node.log().count("dropped a message on /joint_states")
        bad = js(ARM_JOINTS + ["elbow"], Q + [0.0])
        rng = np.random.default_rng(17)
        start, sent, served = time.monotonic(), 0, 0
        while time.monotonic() - start < 3.0:
            for _ in range(50):
                io[JS].publish(bad)
                sent += 1
            q = [float(x) for x in rng.uniform(-1, 1, 7)]
            good = js(ARM_JOINTS, q)
            got = other.exchange(lambda: other_js.publish(good), other_gravity, lambda m: sd.stamp_eq(m.header.stamp, good.header.stamp))
            assert_close(got.effort, ref.pick(ref.gravity(ref.q(ARM_JOINTS, q)), ARM_JOINTS), "gravity for the other client")
            resp = other.call(InverseDynamics, "/spatial_dynamics/inverse_dynamics", InverseDynamics.Request(name=ARM_JOINTS, position=q))
            assert resp.success, resp.message
            served += 1
        elapsed = time.monotonic() - start
        assert served >= 3, f"the other client was served {served} times in {elapsed:.1f} s"
        # One more bad message after a quiet second: its warning reports the suppressed ones.
        ros.spin_for(1.2)
        expect_dropped(ros, io, JS, "unknown joint", lambda: io[JS].publish(js(ARM_JOINTS + ["elbow"], Q + [0.0])), resend=True)
        after = latest_report(ros, io)
        # At most one warning a second (plus one at each end) over all the time bad messages came.
        total = time.monotonic() - start
        counted = sd.dropped_count(after, JS) - sd.dropped_count(before, JS)
        warnings = node.log().count("dropped a message on /joint_states") - warned_before
        print(f"sent {sent} bad joint states in {elapsed:.1f} s: {counted} counted, {warnings} warnings, other client served {served} times")
        # Best effort in: not every message need arrive, but most do on loopback.
        assert counted >= sent // 4, f"only {counted} of {sent} bad messages counted"
        assert 1 <= warnings <= total + 2, f"{warnings} warnings in {total:.1f} s"
        assert "more dropped since the last warning" in node.log(), node.log()[-2000:]
        leaked = [m for m in io["gravity"].messages if sd.stamp_eq(m.header.stamp, bad.header.stamp)]
        assert not leaked, "a bad joint state was answered"
    finally:
        other.close()
