"""Topics in and out on the default arm, values against Pinocchio (default_arm.urdf), stamps echoed.

In: joint_states (best-effort subscriber), ~/effort_command, ~/commands, ~/reference.
Out: ~/gravity_effort, ~/acceleration, ~/feedforward_effort, ~/feedforward_commands, /diagnostics.

Inputs are re-published until the answer arrives: the first samples of a freshly matched writer can
be lost (RustDDS ignores DATA from a writer whose discovery it has not processed yet), and
joint_states is best effort. Answers are told apart by their header stamp (unique per message).
"""

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, DEFAULT_ARM_URDF, assert_close

GRAVITY = "/spatial_dynamics/gravity_effort"
ACCEL = "/spatial_dynamics/acceleration"
FF = "/spatial_dynamics/feedforward_effort"
FFC = "/spatial_dynamics/feedforward_commands"


@pytest.fixture(scope="module")
def io(arm, ros):
    """Collectors on every output, publishers on every input (matched before use)."""
    c = {
        "gravity": ros.collector(JointState, GRAVITY),
        "accel": ros.collector(JointDynamics, ACCEL),
        "ff": ros.collector(JointState, FF),
        "ffc": ros.collector(Float64MultiArray, FFC),
        "diag": ros.collector(DiagnosticArray, "/diagnostics"),
    }
    for col in c.values():
        col.wait_publisher()
    c["js"] = ros.publisher(JointState, "/joint_states", sd.qos_reliable(10))
    c["effort"] = ros.publisher(JointState, "/spatial_dynamics/effort_command", sd.qos_reliable(10))
    c["commands"] = ros.publisher(Float64MultiArray, "/spatial_dynamics/commands", sd.qos_reliable(10))
    c["reference"] = ros.publisher(JointTrajectory, "/spatial_dynamics/reference", sd.qos_reliable(10))
    return c


def joint_state(names, q, v=(), frame_id="base"):
    msg = JointState(name=list(names), position=list(q), velocity=list(v))
    msg.header.stamp = sd.fresh_stamp()
    msg.header.frame_id = frame_id
    return msg


def send_until_answered(ros, io, make_msg, output, extra=None, timeout=sd.EVENT_S, accept=None, pub="js"):
    """Publishes make_msg() (a fresh stamp each time) until `output` answers one of them (and
    `accept(answer)` holds); returns (input message, answer)."""
    sent = []

    def publish():
        if extra:
            extra()
        ros.spin_for(0.02)
        msg = make_msg()
        sent.append(msg)
        io[pub].publish(msg)

    def answers(m):
        return any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent) and (accept is None or accept(m))

    answer = ros.exchange(publish, io[output], answers, timeout=timeout)
    source = next(s for s in sent if sd.stamp_eq(s.header.stamp, answer.header.stamp))
    return source, answer


def test_gravity_effort_matches_pinocchio_with_the_input_stamp(ros, io, ref):
    rng = np.random.default_rng(1)
    names = list(ARM_JOINTS)
    rng.shuffle(names)
    q = sd.random_positions(names, rng, DEFAULT_ARM_URDF)
    v = list(rng.standard_normal(7))
    sent, got = send_until_answered(ros, io, lambda: joint_state(names, q, v, "frame_x"), "gravity")
    assert sd.stamp_eq(got.header.stamp, sent.header.stamp)
    assert got.header.frame_id == "frame_x"
    assert list(got.name) == names
    assert_close(got.position, q, "position echo")
    assert_close(got.effort, ref.pick(ref.gravity(ref.q(names, q)), names), "gravity effort")
    # More states on the now matched topic: one answer each, in order, each right.
    for _ in range(5):
        names = list(ARM_JOINTS)
        rng.shuffle(names)
        q = sd.random_positions(names, rng, DEFAULT_ARM_URDF)
        sent, got = send_until_answered(ros, io, lambda: joint_state(names, q), "gravity")
        assert list(got.name) == names
        assert_close(got.effort, ref.pick(ref.gravity(ref.q(names, q)), names), "gravity effort")


@pytest.mark.parametrize("qos", ["reliable", "best_effort"])
def test_joint_states_from_reliable_and_best_effort_publishers(ros, io, ref, qos):
    profile = sd.qos_reliable(10) if qos == "reliable" else sd.qos_best_effort(10)
    pub = ros.publisher(JointState, "/joint_states", profile)
    q = [0.5, -0.3, 0.2, 0.9, -1.0, 0.4, 3.0]
    sent = []

    def publish():
        msg = joint_state(ARM_JOINTS, q)
        sent.append(msg)
        pub.publish(msg)

    got = ros.exchange(publish, io["gravity"], lambda m: any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent))
    assert_close(got.effort, ref.pick(ref.gravity(ref.q(ARM_JOINTS, q)), ARM_JOINTS), f"gravity effort ({qos})")


def _accel_check(ros, io, ref, names, q, v, command_by_name, send_command):
    """Sends the command with every joint state until ~/acceleration echoes it; checks FD."""
    want_effort = [command_by_name[n] for n in names]
    sent, got = send_until_answered(
        ros, io, lambda: joint_state(names, q, v), "accel", extra=send_command,
        accept=lambda m: list(m.effort) == want_effort,
    )
    assert sd.stamp_eq(got.header.stamp, sent.header.stamp)
    assert list(got.name) == names
    assert_close(got.position, q, "position echo")
    assert_close(got.velocity, v if len(v) else [0.0] * len(names), "velocity echo")
    tau = ref.v(list(command_by_name), list(command_by_name.values()))
    want = ref.pick(ref.aba(ref.q(names, q), ref.v(names, v), tau), names)
    assert_close(got.acceleration, want, "acceleration")
    # The gravity effort of the same message was published too, with the same stamp.
    g = io["gravity"].wait(1, timeout=sd.EVENT_S, predicate=lambda m: sd.stamp_eq(m.header.stamp, sent.header.stamp))[0]
    assert_close(g.effort, ref.pick(ref.gravity(ref.q(names, q)), names), "gravity effort")


def test_effort_command_by_name_drives_the_acceleration(ros, io, ref):
    rng = np.random.default_rng(2)
    cmd_names = list(ARM_JOINTS)
    rng.shuffle(cmd_names)
    command = {n: float(x) for n, x in zip(cmd_names, 5 * rng.standard_normal(7))}
    msg = JointState(name=cmd_names, effort=[command[n] for n in cmd_names])
    names = list(ARM_JOINTS)
    rng.shuffle(names)
    q = sd.random_positions(names, rng, DEFAULT_ARM_URDF)
    v = list(rng.standard_normal(7))
    _accel_check(ros, io, ref, names, q, v, command, lambda: io["effort"].publish(msg))


def test_commands_array_in_model_order_drives_the_acceleration(ros, io, ref):
    rng = np.random.default_rng(3)
    data = [float(x) for x in 3 * rng.standard_normal(7)]
    command = dict(zip(ARM_JOINTS, data))
    names = list(ARM_JOINTS)
    rng.shuffle(names)
    q = sd.random_positions(names, rng, DEFAULT_ARM_URDF)
    _accel_check(ros, io, ref, names, q, [], command, lambda: io["commands"].publish(Float64MultiArray(data=data)))


def trajectory(names, q, v=(), a=()):
    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp = sd.fresh_stamp()
    msg.header.frame_id = "traj"
    msg.points = [
        JointTrajectoryPoint(positions=list(q), velocities=list(v), accelerations=list(a)),
        JointTrajectoryPoint(positions=[0.0] * len(names)),  # later points are not used
    ]
    return msg


@pytest.mark.parametrize("with_rates", [True, False])
def test_reference_gives_feedforward_effort_and_commands(ros, io, ref, with_rates):
    rng = np.random.default_rng(4 if with_rates else 5)
    names = list(ARM_JOINTS)
    rng.shuffle(names)
    q = sd.random_positions(names, rng, DEFAULT_ARM_URDF)
    v = list(rng.standard_normal(7)) if with_rates else []
    a = list(rng.standard_normal(7)) if with_rates else []
    sent, got = send_until_answered(ros, io, lambda: trajectory(names, q, v, a), "ff", pub="reference")
    assert sd.stamp_eq(got.header.stamp, sent.header.stamp)
    assert got.header.frame_id == "traj"
    assert list(got.name) == names
    assert_close(got.position, q, "position echo")
    tau = ref.rnea(ref.q(names, q), ref.v(names, v), ref.v(names, a))
    assert_close(got.effort, ref.pick(tau, names), "feedforward effort")
    # ~/feedforward_commands: the same efforts in command_joints order (default: model order).
    want = ref.pick(tau, ARM_JOINTS)
    ffc = io["ffc"].wait(1, timeout=sd.EVENT_S, predicate=lambda m: len(m.data) == 7 and np.allclose(m.data, want, rtol=0, atol=1e-6))[0]
    assert_close(ffc.data, want, "feedforward commands")
    assert [d.size for d in ffc.layout.dim] == [7]


def test_diagnostics_count_inputs_outputs_and_compute_time(ros, io):
    status_name = "spatial_dynamics: dynamics"
    # Two joint states and a reference, answered, then a report that includes them.
    for _ in range(2):
        send_until_answered(ros, io, lambda: joint_state(ARM_JOINTS, [0.0] * 7), "gravity")
    send_until_answered(ros, io, lambda: trajectory(ARM_JOINTS, [0.0] * 7), "ff", pub="reference")
    io["diag"].clear()
    report = io["diag"].wait(1, timeout=sd.EVENT_S, predicate=lambda m: sd.status_values(m, status_name) is not None)[0]
    values = sd.status_values(report, status_name)
    status = next(s for s in report.status if s.name == status_name)
    assert sd.level(status) == 0 and status.message == "ok", status
    assert values.get("model") == "sd_arm7"
    assert int(values["/joint_states received"]) >= 2
    assert int(values[f"{GRAVITY} published"]) >= 2
    assert int(values[f"{ACCEL} published"]) >= 2
    assert int(values["/spatial_dynamics/reference received"]) >= 1
    assert int(values[f"{FF} published"]) >= 1 and int(values[f"{FFC} published"]) >= 1
    assert float(values["compute mean (us)"]) > 0.0
