"""The node's clock: `use_sim_time` (outputs stamped with the latest /clock; topic inputs dropped
as "waiting for /clock" before the first one), switched at run time, and the input-stamp policy
(`max_stamp_age`, `future_stamp_tolerance`) against simulated and wall-clock time; simulate mode
with `use_sim_time` uses its own simulated time. Values are checked against Pinocchio.
"""

import time

import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics
from spatial_dynamics_msgs.srv import DescribeModel

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

STATUS = "spatial_dynamics: dynamics"
JS = "/joint_states"
DROPPED = "/joint_states"  # the counter's topic name


@pytest.fixture(scope="module")
def io(module_nodes, ros):
    node = module_nodes.start("-p", "use_sim_time:=true", label="sim_time")
    ros.wait_for_service(DescribeModel, "/spatial_dynamics/describe_model")
    c = {
        "node": node,
        "gravity": ros.collector(JointState, "/spatial_dynamics/gravity_effort"),
        "accel": ros.collector(JointDynamics, "/spatial_dynamics/acceleration"),
        "diag": ros.collector(DiagnosticArray, "/diagnostics"),
        "js": ros.publisher(JointState, JS, sd.qos_reliable(10)),
    }
    for name in ("gravity", "accel", "diag"):
        c[name].wait_publisher()
    return c


def t(seconds):
    return Time(sec=int(seconds // 1), nanosec=round((seconds % 1) * 1e9))


def secs(stamp):
    return stamp.sec + 1e-9 * stamp.nanosec


def joint_state(q, stamp):
    msg = JointState(name=ARM_JOINTS, position=list(q))
    msg.header.stamp = stamp
    return msg


def positions(k):
    """A distinct arm configuration per k, so every answer names its input."""
    return [0.1 * k + 0.01 * i for i in range(7)]


def clock_publisher(ros):
    # rclcpp's ClockQoS: best effort, depth 1; waits until the node's /clock reader has matched.
    return ros.publisher(Clock, "/clock", sd.qos_best_effort(1))


def report(ros, c, predicate=lambda v: True, timeout=sd.EVENT_S):
    """The first /diagnostics status of the node (from now on) whose values satisfy `predicate`."""
    c["diag"].clear()
    got = c["diag"].wait(1, timeout, lambda m: (v := sd.status_values(m, STATUS)) is not None and predicate(v))[0]
    return got, sd.status_values(got, STATUS)


def answered_with(ros, c, k, publish, timeout=sd.EVENT_S):
    """Publishes (via `publish(k)`) until the gravity answer for configuration k arrives."""
    want = positions(k)
    return ros.exchange(lambda: publish(k), c["gravity"], lambda m: list(m.position) == want, timeout=timeout)


def test_waits_for_the_first_clock_then_stamps_outputs_with_it(ros, io, ref):
    c = io
    # Before any /clock: nothing is answered, the drops are counted, /diagnostics is stamped 0.
    # joint_states is best effort: sent again after every report until one is counted.
    end = time.monotonic() + sd.EVENT_S
    while True:
        c["js"].publish(joint_state(positions(1), sd.fresh_stamp()))
        array, values = report(ros, c)
        if sd.dropped_count(values, DROPPED, "waiting for /clock") > 0:
            break
        assert time.monotonic() < end, f"no joint_states counted as waiting for /clock: {values}"
    assert values["clock"] == "/clock (use_sim_time)" and values["clock time (s)"] == "none yet", values
    assert (array.header.stamp.sec, array.header.stamp.nanosec) == (0, 0)
    assert not c["gravity"].messages and not c["accel"].messages

    clock = clock_publisher(ros)

    def publish(k, at=100.25):
        clock.publish(Clock(clock=t(at)))
        ros.spin_for(0.01)
        c["js"].publish(joint_state(positions(k), sd.fresh_stamp()))

    got = answered_with(ros, c, 2, publish)
    # Stamped with /clock, not with the input's stamp (sec ≥ 1001) nor the wall clock.
    assert (got.header.stamp.sec, got.header.stamp.nanosec) == (100, 250_000_000)
    q = ref.q(ARM_JOINTS, positions(2))
    assert_close(got.effort, ref.pick(ref.gravity(q), ARM_JOINTS), "gravity effort")
    accel = c["accel"].wait(1, sd.EVENT_S, lambda m: list(m.position) == positions(2))[0]
    assert sd.stamp_eq(accel.header.stamp, got.header.stamp)
    zero = ref.v([], [])
    assert_close(accel.acceleration, ref.pick(ref.aba(q, zero, zero), ARM_JOINTS), "acceleration")
    _, values = report(ros, c, lambda v: v["clock time (s)"] != "none yet")
    assert values["clock time (s)"] == "100.250000000", values

    # /clock going back (a bag that loops) is followed.
    got = answered_with(ros, c, 3, lambda k: publish(k, at=7.5))
    assert secs(got.header.stamp) == 7.5
    assert "/clock went back from 100.250000000 s to 7.500000000 s" in c["node"].log()


def test_stale_and_future_stamps_are_dropped_against_sim_time(ros, io, ref):
    c = io
    results = ros.set_parameters([("max_stamp_age", 0.5), ("future_stamp_tolerance", 0.1)])
    assert all(r.successful for r in results), results
    clock = clock_publisher(ros)
    now = 200.0

    def publish_at(stamp):
        def publish(k):
            clock.publish(Clock(clock=t(now)))
            ros.spin_for(0.01)
            c["js"].publish(joint_state(positions(k), t(stamp)))

        return publish

    # Within the limits: answered, stamped with the clock.
    got = answered_with(ros, c, 4, publish_at(now - 0.45))
    assert secs(got.header.stamp) == now
    answered_with(ros, c, 5, publish_at(now + 0.09))
    _, before = report(ros, c)
    stale0 = sd.dropped_count(before, DROPPED, "stale stamp")
    future0 = sd.dropped_count(before, DROPPED, "stamp from the future")
    # Beyond them: each dropped and counted; a burst gives few warnings (one a second per topic,
    # over however long the burst takes to send and be counted on a busy machine).
    burst_start = time.monotonic()
    for i in range(20):
        publish_at(now - 0.6)(6)
        ros.spin_for(0.005)
    for i in range(5):
        publish_at(now + 0.2)(7)
        ros.spin_for(0.005)
    _, after = report(
        ros, c,
        lambda v: sd.dropped_count(v, DROPPED, "stale stamp") >= stale0 + 20
        and sd.dropped_count(v, DROPPED, "stamp from the future") >= future0 + 5,
    )
    assert sd.dropped_count(after, DROPPED, "stale stamp") == stale0 + 20, after
    assert sd.dropped_count(after, DROPPED, "stamp from the future") == future0 + 5, after
    assert not c["gravity"].matching(lambda m: list(m.position) in (positions(6), positions(7)))
    log = c["node"].log()
    assert "stale stamp (199.400000000 s is 0.600000000 s behind the node's simulated time 200.000000000 s; max_stamp_age 0.500000000 s)" in log
    assert log.count("dropped a message on /joint_states: stale stamp") <= 2 + time.monotonic() - burst_start, log
    # Off again (0): a very old stamp is answered.
    assert all(r.successful for r in ros.set_parameters([("max_stamp_age", 0.0), ("future_stamp_tolerance", 0.0)]))
    answered_with(ros, c, 8, publish_at(3.0))


def test_bad_clock_parameters_are_refused(ros, io):
    types = ros.get_parameter_types(["use_sim_time", "max_stamp_age", "future_stamp_tolerance"])
    assert types == {"use_sim_time": Parameter.Type.BOOL.value, "max_stamp_age": Parameter.Type.DOUBLE.value,
                     "future_stamp_tolerance": Parameter.Type.DOUBLE.value}
    for name, value in (("max_stamp_age", -1.0), ("future_stamp_tolerance", float("inf")), ("use_sim_time", 1)):
        result = ros.set_parameter(name, value)
        assert not result.successful, (name, value)
        assert name in result.reason or "use_sim_time" in result.reason or "type" in result.reason, result.reason
    r = ros.set_parameter("max_stamp_age", -1.0)
    assert "must be a number of seconds ≥ 0" in r.reason, r.reason


def test_use_sim_time_switches_at_run_time_and_wall_clock_policy(ros, io, ref):
    c = io
    assert ros.set_parameter("use_sim_time", False).successful
    # Wall clock: outputs carry their input's stamp.
    stamp = sd.fresh_stamp()
    got = answered_with(ros, c, 9, lambda k: c["js"].publish(joint_state(positions(k), stamp)))
    assert sd.stamp_eq(got.header.stamp, stamp)
    _, values = report(ros, c, lambda v: v["clock"] == "wall clock")
    assert abs(float(values["clock time (s)"]) - time.time()) < 5.0, values
    # Wall-clock stamp policy.
    assert ros.set_parameters([("max_stamp_age", 2.0), ("future_stamp_tolerance", 2.0)])[0].successful
    wall = lambda dt: t(time.time() + dt)
    got = answered_with(ros, c, 10, lambda k: c["js"].publish(joint_state(positions(k), wall(-0.5))))
    _, before = report(ros, c)
    for k, dt in ((11, -30.0), (12, 30.0)):
        c["js"].publish(joint_state(positions(k), wall(dt)))
        ros.spin_for(0.02)
    _, after = report(
        ros, c,
        lambda v: sd.dropped_count(v, DROPPED, "stale stamp") > sd.dropped_count(before, DROPPED, "stale stamp")
        and sd.dropped_count(v, DROPPED, "stamp from the future") > sd.dropped_count(before, DROPPED, "stamp from the future"),
    )
    assert "wall-clock time" in c["node"].log()
    assert ros.set_parameters([("max_stamp_age", 0.0), ("future_stamp_tolerance", 0.0)])[0].successful
    # Back to simulated time: the old /clock is forgotten until a new one arrives.
    assert ros.set_parameter("use_sim_time", True).successful
    _, values = report(ros, c, lambda v: v["clock"] == "/clock (use_sim_time)")
    assert values["clock time (s)"] == "none yet", values
    clock = clock_publisher(ros)

    def publish(k):
        clock.publish(Clock(clock=t(55.0)))
        ros.spin_for(0.01)
        c["js"].publish(joint_state(positions(k), sd.fresh_stamp()))

    got = answered_with(ros, c, 13, publish)
    assert secs(got.header.stamp) == 55.0


def test_simulate_mode_with_use_sim_time_is_stamped_with_its_own_time(ros, nodes):
    ns = "/simtime"
    nodes.start("-r", f"__ns:={ns}", "-p", "mode:=simulate", "-p", "use_sim_time:=true", "-p", "publish_rate:=50.0",
                "-p", "max_stamp_age:=0.1", label="simulate_sim_time")
    states = ros.collector(JointState, f"{ns}/joint_states", sd.qos_best_effort())
    gravity = ros.collector(JointState, f"{ns}/spatial_dynamics/gravity_effort")
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    # A foreign /clock far away is ignored: the simulating node is its own clock.
    foreign = ros.node.create_publisher(Clock, "/clock", sd.qos_best_effort(1))
    end = time.monotonic() + 10
    while len(gravity.messages) < 20 and time.monotonic() < end:
        foreign.publish(Clock(clock=t(5000.0)))
        ros.spin_for(0.05)
    ros.node.destroy_publisher(foreign)
    assert len(gravity.messages) >= 20, f"{len(gravity.messages)} answers"
    # Each answer carries the simulated time (seconds since start, not 5000 s, not wall time)
    # reached when its input arrived: that of its input (found by its position; the arm falls
    # under gravity, so every state differs).
    stamp_of = {tuple(m.position): (m.header.stamp.sec, m.header.stamp.nanosec) for m in states.messages}
    out = [(tuple(m.position), (m.header.stamp.sec, m.header.stamp.nanosec)) for m in gravity.messages]
    assert all(s[0] < 100 for _, s in out), out
    matched = [(s, stamp_of[q]) for q, s in out if q in stamp_of]
    assert len(matched) >= 0.5 * len(out), f"{len(matched)} of {len(out)} answers to a joint_states seen here"
    assert all(a == b for a, b in matched), matched
    # diagnostic_updater names a status by the node's base name: the module's node at the root
    # has the same one; this node's status is the one counting its namespace's topics.
    status_name = "spatial_dynamics: dynamics"

    def own(m):
        return next((s for s in m.status if s.name == status_name and any(kv.key.startswith(f"{ns}/") for kv in s.values)), None)

    got = diag.wait(1, sd.EVENT_S, lambda m: own(m) is not None)[0]
    values = {kv.key: kv.value for kv in own(got).values}
    assert values["clock"] == "own simulated time (use_sim_time, simulate mode)", values
    # Its own joint_states are never stale against its own time (max_stamp_age 0.1 s).
    assert sd.dropped_count(values, f"{ns}/joint_states") == 0, values
