"""The node never publishes a non-finite number: inputs that are finite but extreme enough to
overflow (velocities 1e200, efforts 1e300, a reference moving at 1e200) are tried on every topic
and service. Whatever the node answers is finite; what it cannot answer finitely is dropped and
counted on /diagnostics (a service says why with success=false). In simulate mode, a command of
1e300 N·m stops the simulation (level ERROR on /diagnostics) and nothing non-finite goes out on
joint_states.

Every message received on every output during the module is checked, not just the ones matched
to an input.
"""

import math
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics
from spatial_dynamics_msgs.srv import DescribeModel, ForwardDynamics, InverseDynamics, MassMatrix
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

NODE = "/spatial_dynamics"
STATUS = "spatial_dynamics: dynamics"
JS = "/joint_states"
Q = [0.4, -0.6, 0.3, 1.2, -0.5, 0.8, -2.5]
HUGE_V = [1e200] * 7


def all_finite(msg, fields):
    return all(math.isfinite(x) for f in fields for x in getattr(msg, f))


OUTPUTS = {
    "gravity": (JointState, f"{NODE}/gravity_effort", ("position", "velocity", "effort")),
    "accel": (JointDynamics, f"{NODE}/acceleration", ("position", "velocity", "acceleration", "effort")),
    "ff": (JointState, f"{NODE}/feedforward_effort", ("position", "velocity", "effort")),
    "ffc": (Float64MultiArray, f"{NODE}/feedforward_commands", ("data",)),
    "residual": (JointState, f"{NODE}/effort_residual", ("position", "velocity", "effort")),
}


@pytest.fixture(scope="module")
def io(module_nodes, ros):
    module_nodes.start(label="arm")
    ros.wait_for_service(DescribeModel, f"{NODE}/describe_model")
    c = {key: ros.collector(t, topic) for key, (t, topic, _) in OUTPUTS.items()}
    c["diag"] = ros.collector(DiagnosticArray, "/diagnostics")
    for col in c.values():
        col.wait_publisher()
    c["js"] = ros.publisher(JointState, JS, sd.qos_reliable(10))
    c["effort"] = ros.publisher(JointState, f"{NODE}/effort_command", sd.qos_reliable(10))
    c["reference"] = ros.publisher(JointTrajectory, f"{NODE}/reference", sd.qos_reliable(10))
    yield c
    # Everything published during the module, matched to an input or not, was finite.
    for key, (_, topic, fields) in OUTPUTS.items():
        bad = [m for m in c[key].messages if not all_finite(m, fields)]
        assert not bad, f"{topic} published a non-finite number: {bad[0]}"


def js(q=Q, v=()):
    msg = JointState(name=ARM_JOINTS, position=list(q), velocity=list(v))
    msg.header.stamp = sd.fresh_stamp()
    return msg


def drops(ros, c, topic):
    c["diag"].clear()
    got = c["diag"].wait(1, sd.EVENT_S, lambda m: sd.status_values(m, STATUS) is not None)[0]
    return sd.dropped_count(sd.status_values(got, STATUS), topic), sd.status_values(got, STATUS)


def wait_drops(ros, c, topic, above, send, timeout=sd.EVENT_S):
    """Sends (again each second: joint_states is best effort) until /diagnostics counts more than
    `above` drops on `topic`; returns the report's values."""
    end = ros.node.get_clock().now().nanoseconds + int(timeout * 1e9)
    while True:
        send()
        count, values = drops(ros, c, topic)
        if count > above:
            return values
        assert ros.node.get_clock().now().nanoseconds < end, f"no drop counted on {topic}: {values}"


def answered_after(ros, c, key, publisher, make):
    """Sends good inputs until one is answered on output `key`: an answer to any earlier input
    has then arrived too (one writer per output, in order)."""
    sent = []

    def publish():
        sent.append(make())
        publisher.publish(sent[-1])

    ros.exchange(publish, c[key], lambda m: any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent))


def good_reference():
    msg = JointTrajectory(joint_names=ARM_JOINTS, points=[JointTrajectoryPoint(positions=Q)])
    msg.header.stamp = sd.fresh_stamp()
    return msg


def test_joint_states_moving_at_1e200_are_dropped_and_counted_not_published(ros, io):
    before, _ = drops(ros, io, JS)
    sent = []

    def send():
        sent.append(js(v=HUGE_V))
        io["js"].publish(sent[-1])

    values = wait_drops(ros, io, JS, before, send)
    kinds = [k for k in values if k.startswith(f"{JS} dropped: ") and "acceleration" in k]
    assert kinds, f"no drop counted as an acceleration overflow: {values}"
    for key in ("gravity", "accel"):
        answered_after(ros, io, key, io["js"], js)
    for key in ("gravity", "accel"):
        leaked = [m for m in io[key].messages if any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent)]
        assert not leaked, f"{key} answered a state moving at 1e200: {leaked[0]}"


def test_huge_effort_commands_give_finite_accelerations_or_none(ros, io, ref):
    """A command of 1e300 N·m is finite and so is the acceleration it causes (about 1e302): it is
    published, and equals Pinocchio's. A command of 1.7e308 overflows the acceleration: joint
    states are then dropped and counted, nothing is published, until a sane command arrives."""

    def answered_under(command, label):
        sent = []

        def publish():
            io["effort"].publish(JointState(name=ARM_JOINTS, effort=command))
            ros.spin_for(0.02)
            sent.append(js())
            io["js"].publish(sent[-1])

        got = ros.exchange(publish, io["accel"], lambda m: list(m.effort) == command and any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent))
        want = ref.aba(ref.q(ARM_JOINTS, Q), ref.v([], []), ref.v(ARM_JOINTS, command))
        assert_close(got.acceleration, ref.pick(want, ARM_JOINTS), label)

    answered_under([1e300] * 7, "acceleration under 1e300 N·m")
    io["effort"].publish(JointState(name=ARM_JOINTS, effort=[1.7e308] * 7))
    before, _ = drops(ros, io, JS)
    values = wait_drops(ros, io, JS, before, lambda: io["js"].publish(js()))
    assert any("acceleration" in k for k in values if k.startswith(f"{JS} dropped: ")), values
    answered_under([1.0, -2.0, 0.5, 3.0, -0.25, 0.75, 0.1], "acceleration under a sane command")


def test_a_reference_moving_at_1e200_is_dropped_and_counted(ros, io):
    topic = f"{NODE}/reference"
    before, _ = drops(ros, io, topic)
    sent = []

    def send():
        msg = JointTrajectory(joint_names=ARM_JOINTS, points=[JointTrajectoryPoint(positions=Q, velocities=HUGE_V)])
        msg.header.stamp = sd.fresh_stamp()
        sent.append(msg)
        io["reference"].publish(msg)

    values = wait_drops(ros, io, topic, before, send)
    assert any("tau" in k for k in values if k.startswith(f"{topic} dropped: ")), values
    answered_after(ros, io, "ff", io["reference"], good_reference)
    leaked = [m for m in io["ff"].messages if any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent)]
    assert not leaked, f"feedforward_effort answered a reference moving at 1e200: {leaked[0]}"


SERVICES = {
    "id_velocity_1e200": (InverseDynamics, dict(name=ARM_JOINTS, position=Q, velocity=HUGE_V), "effort"),
    "fd_velocity_1e200": (ForwardDynamics, dict(name=ARM_JOINTS, position=Q, velocity=HUGE_V), "acceleration"),
    "fd_effort_1e300": (ForwardDynamics, dict(name=ARM_JOINTS, position=Q, effort=[1e300] * 7), "acceleration"),
    "id_acceleration_1e300": (InverseDynamics, dict(name=ARM_JOINTS, position=Q, acceleration=[1e300] * 7), "effort"),
}


@pytest.mark.parametrize("case", list(SERVICES))
def test_services_answer_finite_or_refuse_with_the_reason(ros, io, case):
    srv, fields, array = SERVICES[case]
    leaf = {InverseDynamics: "inverse_dynamics", ForwardDynamics: "forward_dynamics"}[srv]
    resp = ros.call(srv, f"{NODE}/{leaf}", srv.Request(**fields))
    if resp.success:
        assert all(math.isfinite(x) for x in getattr(resp, array)), resp
    else:
        assert "overflowed to a non-finite value" in resp.message, resp.message
        assert len(getattr(resp, array)) == 0


def test_mass_matrix_is_finite_at_any_finite_angle(ros, io):
    resp = ros.call(MassMatrix, f"{NODE}/mass_matrix", MassMatrix.Request(name=ARM_JOINTS, position=[1e300] * 7))
    assert resp.success and all(math.isfinite(x) for x in resp.matrix), resp


def test_simulation_driven_at_1e300_stops_and_publishes_nothing_non_finite(nodes, ros):
    # rk4 at 1 ms keeps the unforced arm's energy (semi-implicit Euler may stop it for that).
    nodes.start("-p", "mode:=simulate", "-p", "integrator:=rk4", "-p", "publish_rate:=50.0", "-p", "command_timeout:=0.0", "-r", "__node:=sim", label="sim")
    sim_js = ros.collector(JointState, JS, sd.qos_best_effort(50))
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    sim_js.wait(3, sd.EVENT_S)
    commands = ros.publisher(Float64MultiArray, "/sim/commands", sd.qos_reliable(10))

    def status(m):
        return next((s for s in m.status if s.name == "sim: dynamics"), None)

    def stopped():
        return any(status(m) is not None and sd.level(status(m)) == 2 for m in diag.messages)

    end = time.monotonic() + sd.EVENT_S
    while not stopped():  # again until it takes effect (a new writer's first sample may be lost)
        assert time.monotonic() < end, "the simulation did not stop"
        commands.publish(Float64MultiArray(data=[1e300] * 7))
        ros.spin_for(0.3)
    message = next(status(m).message for m in diag.messages if status(m) is not None and sd.level(status(m)) == 2)
    print(f"simulation stopped: {message}")
    assert "overflowed" in message or "no longer finite" in message, message
    ros.spin_for(0.5)
    bad = [m for m in sim_js.messages if not all_finite(m, ("position", "velocity", "effort"))]
    assert not bad, f"simulated joint_states with a non-finite number: {bad[0]}"
