"""Live replay: a synthetic rosbag2 bag (sqlite3 and MCAP) of the default arm moving along a smooth
trajectory, with efforts commanded on ~/effort_command, is played by launch_scripts/play_bag.py
into a node started with use_sim_time:=true; the node's ~/gravity_effort and ~/acceleration are
recorded into a bag with rosbags' writer from an rclpy subscriber, read back, and checked:

* stamps are bag time (the bag starts at t = 1000 s, far from the wall clock), and exactly the
  bag time of the joint_states they answer (play_bag publishes /clock just before each
  joint_states, --clock-topics); the recorded header stamps are 0.7 ms earlier, so the check
  also tells /clock stamping from copying the input stamp;
* values against Pinocchio on the same URDF: computeGeneralizedGravity(q) and
  aba(q, v, τ_cmd) for the input with that stamp.
"""

import collections
import math
import subprocess
import sys
import time

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics
from spatial_dynamics_msgs.srv import DescribeModel

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, DEFAULT_ARM_URDF, REPO

NS = 1_000_000_000
T0 = 1000 * NS  # bag start: 1000 s, far from the wall clock
JS_PERIOD = 4_000_000  # joint_states at 250 Hz
CMD_PERIOD = 20_000_000  # effort commands at 50 Hz, 1 ms before a joint_states
DURATION = 2 * NS
HEADER_LAG = 700_000  # header stamp = bag time − 0.7 ms (a driver's measurement time)
GRAVITY = "/spatial_dynamics/gravity_effort"
ACCEL = "/spatial_dynamics/acceleration"
EFFORT = "/spatial_dynamics/effort_command"


def typestore():
    store = get_typestore(Stores.ROS2_JAZZY)
    text = (REPO / "msg" / "msg" / "JointDynamics.msg").read_text()
    store.register(get_types_from_msg(text, "spatial_dynamics_msgs/msg/JointDynamics"))
    return store


def trajectory(t):
    """q(t), q̇(t) of a smooth motion (rad, rad/s), t in seconds from the bag's start."""
    a = np.array([0.8, 0.6, 0.7, 0.9, 1.0, 0.7, 1.2])
    w = np.array([1.1, 1.7, 2.3, 1.3, 2.9, 3.1, 1.9])
    phi = np.arange(7) * 0.4
    return a * np.sin(w * t + phi), a * w * np.cos(w * t + phi)


def command(t):
    """The commanded effort at time t (N·m)."""
    return np.array([5.0, -20.0, 3.0, 10.0, -1.0, 0.5, 0.2]) * (1.0 + 0.5 * math.sin(3.0 * t))


def stamp(n):
    return Time(sec=n // NS, nanosec=n % NS)


def write_input_bag(path, storage):
    """The synthetic bag; returns {bag time: (q, v)} of joint_states and [(bag time, τ)]."""
    best_effort = Qos(QosHistory.KEEP_LAST, 10, QosReliability.BEST_EFFORT, QosDurability.VOLATILE,
                      QosTime(0, 0), QosTime(0, 0), QosLiveliness.AUTOMATIC, QosTime(0, 0), False)
    store = typestore()
    states, commands = {}, []
    with Writer(path, version=9, storage_plugin=storage) as writer:
        js = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store,
                                   offered_qos_profiles=[best_effort])
        cmd = writer.add_connection(EFFORT, "sensor_msgs/msg/JointState", typestore=store)
        events = [(n, "js") for n in range(T0, T0 + DURATION, JS_PERIOD)]
        events += [(n, "cmd") for n in range(T0 + JS_PERIOD - 1_000_000, T0 + DURATION, CMD_PERIOD)]
        for n, kind in sorted(events):
            t = (n - T0) / NS
            msg = JointState(name=ARM_JOINTS)
            if kind == "js":
                q, v = trajectory(t)
                msg.header.stamp = stamp(n - HEADER_LAG)
                msg.position, msg.velocity = q.tolist(), v.tolist()
                states[n] = (q, v)
                writer.write(js, n, serialize_message(msg))
            else:
                tau = command(t)
                msg.header.stamp = stamp(n)
                msg.effort = tau.tolist()
                commands.append((n, tau))
                writer.write(cmd, n, serialize_message(msg))
    return states, commands


class Recorder:
    """Records topics as they arrive (serialized, as ros2 bag record does) into a rosbags writer."""

    def __init__(self, ros, path, topics):
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.count = {}
        self.subs = []
        store = typestore()
        for topic, cls, msgtype in topics:
            conn = self.writer.add_connection(topic, msgtype, typestore=store)
            self.count[topic] = 0

            def received(raw, conn=conn, topic=topic):
                self.writer.write(conn, time.time_ns(), raw)
                self.count[topic] += 1

            self.subs.append(ros.node.create_subscription(cls, topic, received, sd.qos_reliable(depth=2000), raw=True))

    def close(self, ros):
        for sub in self.subs:
            ros.node.destroy_subscription(sub)
        self.writer.close()


def read_bag(path):
    store = typestore()
    out = {}
    with Reader(path) as reader:
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(store.deserialize_cdr(raw, conn.msgtype))
    return out


@pytest.fixture(scope="module")
def node(module_nodes, ros):
    node = module_nodes.start("-p", "use_sim_time:=true", label="replay")
    ros.wait_for_service(DescribeModel, "/spatial_dynamics/describe_model")
    return node


@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP], ids=["sqlite3", "mcap"])
def test_replayed_bag_is_answered_in_bag_time_like_pinocchio(ros, node, tmp_path, storage):
    states, commands = write_input_bag(tmp_path / "input", storage)
    recorder = Recorder(ros, tmp_path / "output", [(GRAVITY, JointState, "sensor_msgs/msg/JointState"),
                                                   (ACCEL, JointDynamics, "spatial_dynamics_msgs/msg/JointDynamics")])
    ros.spin_until(lambda: all(s.get_publisher_count() > 0 for s in recorder.subs), sd.EVENT_S)
    player = play(tmp_path / "input", "--clock-topics", "/joint_states", "--wait-for-subscribers", "10",
                  "--delay", "0.5")
    ros.spin_until(lambda: player.poll() is not None, 3 * sd.EVENT_S)
    report = player.communicate(timeout=10)[0]
    assert player.returncode == 0, report
    # Every answer, or as many as arrive (joint_states is best effort) within a bound.
    ros.spin_until(lambda: recorder.count[ACCEL] >= len(states), 10.0)
    recorder.close(ros)
    assert f"/joint_states: {len(states)}" in report, report

    got = read_bag(tmp_path / "output")
    ref = sd.PinRef(DEFAULT_ARM_URDF)
    bag_times = sorted(states)
    by_position = {q.tobytes(): n for n, (q, _) in states.items()}
    assert len(by_position) == len(states)
    lags = {}
    for topic in (GRAVITY, ACCEL):
        messages = got.get(topic, [])
        # Best effort on loopback under a loaded machine: nearly all answered.
        assert len(messages) >= 0.9 * len(states), f"{topic}: {len(messages)} answers to {len(states)} joint_states"
        lags[topic] = []
        for m in messages:
            n = m.header.stamp.sec * NS + m.header.stamp.nanosec
            # Bag time, not wall time, and never the header's own stamp.
            assert T0 <= n < T0 + DURATION, f"{topic}: stamp {n / NS} s is not bag time"
            assert n in states, f"{topic}: stamp {n / NS} s is no joint_states' bag time"
            # The input answered: the one with this position (all differ along the trajectory).
            answered = by_position.get(np.asarray(m.position).tobytes())
            assert answered is not None, f"{topic}: at {n / NS} s, the position of no input"
            # Its /clock, or a later one if the next joint_states' /clock had arrived before the
            # node got to it. DDS orders samples within a topic, not across topics: on a loaded
            # machine an input can overtake its own /clock, and is then stamped with the
            # previous input's bag time, never earlier.
            lag = bag_times.index(n) - bag_times.index(answered)
            assert lag >= -1, f"{topic}: input of {answered / NS} s stamped {n / NS} s"
            lags[topic].append(lag)
            q_in, v_in = states[answered]
            q = ref.q(ARM_JOINTS, q_in)
            assert list(m.name) == ARM_JOINTS
            if topic == GRAVITY:
                sd.assert_close(m.effort, ref.pick(ref.gravity(q), ARM_JOINTS), f"gravity at {n / NS} s")
            else:
                tau = np.asarray(m.effort)
                # The effort in force is a commanded one (zero before the first arrives) ...
                assert not tau.any() or any(np.array_equal(tau, c) for _, c in commands), tau
                want = ref.pick(ref.aba(q, ref.v(ARM_JOINTS, v_in), ref.v(ARM_JOINTS, tau)), ARM_JOINTS)
                sd.assert_close(m.velocity, v_in, f"velocity at {n / NS} s")
                sd.assert_close(m.acceleration, want, f"acceleration at {n / NS} s")
        # Stamped with the /clock that arrived just before their own input (the node takes the
        # /clock received before the input, however late it gets to it).
        off = sum(lag != 0 for lag in lags[topic])
        assert off <= 0.01 * len(messages), f"{topic}: {off} stamped off their input; lags {sorted(collections.Counter(lags[topic]).items())}"
    # ... and the recorded commands do take effect: answers use the latest command before their
    # joint_states (how many depends on the machine's load, not on the node: DDS orders nothing
    # across topics and the node applies a command when it processes it, so on a loaded machine
    # an answer may use an older command, zero or an earlier run's, before the first arrives).
    where = {"latest": 0, "other": 0}
    accel = got[ACCEL]
    for m in accel:
        n = m.header.stamp.sec * NS + m.header.stamp.nanosec
        i = sum(1 for t, _ in commands if t < n) - 1  # the latest command before n
        if i >= 0 and np.array_equal(np.asarray(m.effort), commands[i][1]):
            where["latest"] += 1
        else:
            where["other"] += 1
    assert where["latest"] > 0, where
    print(f"{storage.name}: {len(got[GRAVITY])}/{len(got[ACCEL])} answers to {len(states)} joint_states; "
          f"stamped late by k inputs (counts for k = 0, 1, …): { {t: np.bincount(v).tolist() for t, v in lags.items()} }; "
          f"commands in effect: {where}")


PLAYERS = []  # every player started by the running test


def play(bag, *options):
    """play_bag.py BAG OPTIONS, stopped after the test by no_player_outlives_its_test and, should
    pytest itself be killed, by the parent-death signal."""
    player = subprocess.Popen([*sd.DIE_WITH_TESTS, sys.executable, str(REPO / "launch_scripts" / "play_bag.py"),
                               str(bag), *options],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    PLAYERS.append(player)
    return player


@pytest.fixture(autouse=True)
def no_player_outlives_its_test():
    """A player a failing test left running (a --loop one never ends by itself) is killed."""
    yield
    while PLAYERS:
        player = PLAYERS.pop()
        if player.poll() is None:
            player.kill()
        player.communicate(timeout=10)


def test_player_rate_offset_topics_clock_and_loop(ros, tmp_path):
    """play_bag alone: --rate, --start-offset, --topics, periodic --clock, --loop (no node needed)."""
    from rosgraph_msgs.msg import Clock

    states, _ = write_input_bag(tmp_path / "bag", StoragePlugin.MCAP)
    # Every topic remapped under /player_test, away from the module's node: --wait-for-subscribers
    # then waits for this test's own subscriptions.
    remap = ["--remap", "/joint_states:=/player_test/joint_states", f"{EFFORT}:=/player_test/effort",
             "/clock:=/player_test/clock"]
    cmd = ros.collector(JointState, "/player_test/effort", sd.qos_reliable(2000))
    clock = ros.collector(Clock, "/player_test/clock", sd.qos_best_effort(2000))
    received = []  # (arrival, joint_states)
    ros.node.create_subscription(JointState, "/player_test/joint_states", lambda m: received.append((time.monotonic(), m)),
                                 sd.qos_best_effort(2000))
    # Second half of the bag at twice the speed, joint_states only, /clock at 50 Hz.
    player = play(tmp_path / "bag", "--rate", "2", "--start-offset", "1.0", "--topics", "/joint_states",
                  "--clock", "50", "--wait-for-subscribers", "10", "--delay", "0.3", *remap)
    ros.spin_until(lambda: player.poll() is not None, 3 * sd.EVENT_S)
    report = player.communicate(timeout=5)[0]
    second_half = [n for n in states if n >= T0 + NS]
    # Every message, or as many as arrive (best effort) within a bound.
    ros.spin_until(lambda: len(received) >= len(second_half), 10.0)
    print(report)
    assert player.returncode == 0, report
    assert len(received) >= 0.95 * len(second_half), (len(received), report)
    assert not cmd.messages, "--topics left out the effort commands"
    firsts = [m.header.stamp.sec * NS + m.header.stamp.nanosec + HEADER_LAG for _, m in received]
    assert min(firsts) >= T0 + NS
    wall = received[-1][0] - received[0][0]
    bag = (max(firsts) - min(firsts)) / NS
    assert abs(wall - bag / 2) < 0.2 * bag / 2 + 0.05, f"{bag} s of bag in {wall} s at --rate 2"
    ticks = [c.clock.sec * NS + c.clock.nanosec for c in clock.messages]
    assert all(T0 + NS <= t <= T0 + DURATION for t in ticks), ticks
    assert all(b >= a for a, b in zip(ticks, ticks[1:])), "/clock went back within one pass"
    assert 0.6 * 50 * wall <= len(ticks) <= 1.4 * 50 * wall + 2, f"{len(ticks)} /clock in {wall} s at 50 Hz"

    # --loop: plays again from the start; /clock (per message) jumps back; stopped by SIGINT.
    clock.clear()
    player = play(tmp_path / "bag", "--loop", "--rate", "4", "--start-offset", "1.5", "--clock-topics-all",
                  "--wait-for-subscribers", "10", *remap)
    ros.spin_until(lambda: sum(1 for a, b in zip(clock.messages, clock.messages[1:])
                               if b.clock.sec * NS + b.clock.nanosec < a.clock.sec * NS + a.clock.nanosec) >= 2, sd.EVENT_S)
    player.send_signal(2)
    report = player.communicate(timeout=5)[0]
    assert player.returncode == 0, report
    print(report)
    assert "pass(es)" in report and not report.startswith("play_bag: 0 pass"), report
    backs = sum(1 for a, b in zip(clock.messages, clock.messages[1:])
                if b.clock.sec * NS + b.clock.nanosec < a.clock.sec * NS + a.clock.nanosec)
    assert backs >= 2, f"/clock jumped back {backs} times"
