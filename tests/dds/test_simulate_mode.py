"""Simulate mode: the node owns the arm's state, integrates it from ~/commands, publishes
joint_states and /clock, and serves ~/reset, ~/pause and ~/step.

The motion is checked against `spatial_dynamics simulate` run offline with the same inputs
(same initial state, same constant efforts, same integrator and step): driving the node by
~/step while paused makes its timeline exactly that of the offline run.
"""

import csv
import json
import subprocess

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.srv import DescribeModel, Reset
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS

NODE = "/spatial_dynamics"
Q0 = [0.1, 0.7, -0.2, -1.1, 0.3, 0.5, 0.0]
EFFORT = [1.0, 25.0, -2.0, 8.0, 0.5, 1.0, 0.2]
STEPS = 150
DT = 0.001


@pytest.fixture(scope="module")
def sim(module_nodes, ros):
    node = module_nodes.start(
        "-p", "mode:=simulate", "-p", "integrator:=rk4", "-p", f"sim_dt:={DT}", "-p", "publish_rate:=50.0",
        "-p", "publish_clock:=true", "-p", "command_timeout:=0.0", label="simulate",
    )
    ros.wait_for_service(DescribeModel, f"{NODE}/describe_model")
    return node


def offline(tmp_path):
    """The same run with the command-line simulator: the final row's positions and velocities."""
    out = tmp_path / "offline.csv"
    subprocess.run(
        [str(sd.binary_path()), "simulate", "--integrator", "rk4", "--dt", str(DT), "--duration", str(STEPS * DT),
         "--initial", json.dumps(dict(zip(ARM_JOINTS, Q0))), "--effort", json.dumps(dict(zip(ARM_JOINTS, EFFORT))),
         "--output", str(out)],
        check=True,
    )
    rows = list(csv.DictReader(open(out)))
    last = rows[-1]
    return np.array([float(last[f"{j}.position"]) for j in ARM_JOINTS]), np.array([float(last[f"{j}.velocity"]) for j in ARM_JOINTS])


def test_runs_in_real_time_with_clock(ros, sim):
    states = ros.collector(JointState, "/joint_states", sd.qos_best_effort())
    clocks = ros.collector(Clock, "/clock", sd.qos_best_effort())
    states.wait(n=20, timeout=sd.EVENT_S)
    clocks.wait(n=20, timeout=sd.EVENT_S)
    stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in states.messages]
    steps = np.diff(stamps)
    # publish_rate 50 Hz with real_time_factor 1: the simulated time advances 20 ms per message.
    assert np.allclose(steps[steps > 0], 0.02, atol=1e-9), steps
    assert states.messages[-1].name == ARM_JOINTS
    assert all(np.isfinite(m.position).all() and np.isfinite(m.velocity).all() for m in states.messages)
    # /diagnostics reports the simulation: time, real-time factor (about 1 here), clamps.
    diagnostics = ros.collector(DiagnosticArray, "/diagnostics")
    array = diagnostics.wait(n=2, timeout=sd.EVENT_S)[-1]
    values = {kv.key: kv.value for status in array.status for kv in status.values}
    assert float(values["simulated time (s)"]) > 0
    assert 0.5 < float(values["real-time factor"]) < 1.5, values
    assert values["paused"] == "false" and values["efforts clamped"] == "0", values
    assert values["steps halved (implicit Euler)"] == "0", values


def test_commands_drive_the_arm_like_the_offline_simulator(ros, sim, tmp_path):
    assert ros.call(SetBool, f"{NODE}/pause", SetBool.Request(data=True)).success
    reset = ros.call(Reset, f"{NODE}/reset", Reset.Request(name=ARM_JOINTS, position=Q0, velocity=[]))
    assert reset.success, reset.message
    try:
        # Paused, nothing moves while the command arrives: publish it until /diagnostics counts
        # it (the first samples of a fresh writer can be lost while discovery settles).
        commands = ros.publisher(Float64MultiArray, f"{NODE}/commands")
        diagnostics = ros.collector(DiagnosticArray, "/diagnostics")
        ros.exchange(lambda: commands.publish(Float64MultiArray(data=EFFORT)), diagnostics, commands_counted, timeout=sd.EVENT_S, period=0.3)
        states = ros.collector(JointState, "/joint_states", sd.qos_reliable())
        for _ in range(STEPS):
            answer = ros.call(Trigger, f"{NODE}/step", Trigger.Request())
            assert answer.success, answer.message
        last = states.wait(n=STEPS, timeout=sd.EVENT_S)[-1]
        assert list(last.effort) == EFFORT, "the command in force is echoed as effort"
        q, v = offline(tmp_path)
        np.testing.assert_allclose(last.position, q, rtol=0, atol=1e-9)
        np.testing.assert_allclose(last.velocity, v, rtol=0, atol=1e-9)
    finally:
        assert ros.call(SetBool, f"{NODE}/pause", SetBool.Request(data=False)).success


def commands_counted(array):
    """True when a /diagnostics message counts at least one message received on ~/commands."""
    return any(kv.key == f"{NODE}/commands received" and int(kv.value) >= 1 for status in array.status for kv in status.values)


def test_bad_reset_and_step_while_running_are_refused(ros, sim):
    bad = ros.call(Reset, f"{NODE}/reset", Reset.Request(name=["joint1", "elbow"], position=[0.0, 0.0]))
    assert not bad.success and "elbow" in bad.message
    running = ros.call(Trigger, f"{NODE}/step", Trigger.Request())
    assert not running.success and "pause" in running.message


def test_parameter_changes_do_not_add_publish_ticks(nodes, ros):
    """A parameter set while simulating keeps the publish timer's pace: at 0.5 Hz (a tick every
    2 s, each 2 s of simulated time) ten quick sets of `method` publish no extra joint state.
    (In its own namespace: the module's simulating node publishes /joint_states.)"""
    node = "/slow/spatial_dynamics"
    nodes.start("-p", f"urdf_file:={sd.PARTICLE_URDF}", "-p", "mode:=simulate", "-p", "publish_rate:=0.5",
                "-p", "gravity:=[0.0,0.0,0.0]", "-r", "__ns:=/slow", label="slow ticks")
    ros.wait_for_service(DescribeModel, f"{node}/describe_model")
    states = ros.collector(JointState, "/slow/joint_states")
    states.wait_publisher()
    for i in range(10):
        assert ros.set_parameter("method", "aba" if i % 2 == 0 else "crba", node=node).successful
    ros.spin_for(1.0)
    # At most the one tick the timer may have had due within that second.
    assert len(states.messages) <= 1, [sd.stamp_ns(m) * 1e-9 for m in states.messages]
