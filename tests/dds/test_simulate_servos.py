"""Simulate mode with position servos in lockstep: ~/joint_commands (sensor_msgs/JointState by
name, as topic_based_ros2_control publishes them) set PD targets; each accepted command advances
the simulation by steps_per_command * sim_dt and publishes joint_states once.

Checked against Pinocchio: a PD holding the default arm against gravity settles where
kp (q_cmd - q) = g(q), Pinocchio's generalized gravity at the settled q. Lockstep: a closed-loop
rclpy controller run twice from the same reset gives bit-identical joint states, one message per
command, stamps exactly steps_per_command * sim_dt apart. Bad commands are dropped and counted.
"""

import math

import numpy as np
import pinocchio as pin
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.srv import DescribeModel, Reset

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS

NODE = "/spatial_dynamics"
DT_NS = 1_000_000
STEPS = 250
TARGET = [0.3, 0.6, -0.4, -0.9, 0.2, 0.4, 0.1]
REF = sd.PinRef(urdf_path=sd.DEFAULT_ARM_URDF)
# Per joint: kp, and kd critically damping the joint's own inertia at the target (2 sqrt(kp I)).
KP = [200.0, 600.0, 100.0, 300.0, 20.0, 40.0, 5.0]
_H = pin.crba(REF.model, REF.model.createData(), REF.q(ARM_JOINTS, TARGET))
KD = [2.0 * math.sqrt(kp * _H[REF.joints[j].idx_v, REF.joints[j].idx_v]) for kp, j in zip(KP, ARM_JOINTS)]


@pytest.fixture(scope="module")
def sim(module_nodes, ros):
    node = module_nodes.start(
        "-p", "mode:=simulate", "-p", "command_interface:=position", "-p", f"servo_kp:={KP}",
        "-p", f"servo_kd:={KD}", "-p", "step_mode:=on_command", "-p", f"steps_per_command:={STEPS}",
        label="servos",
    )
    ros.wait_for_service(DescribeModel, f"{NODE}/describe_model")
    return node


def reset(ros):
    r = ros.call(Reset, f"{NODE}/reset", Reset.Request(name=ARM_JOINTS, position=[0.0] * 7, velocity=[]))
    assert r.success, r.message


def test_a_position_pd_holds_the_arm_short_of_its_target_by_gravity_over_kp(ros, sim):
    reset(ros)
    states = ros.collector(JointState, "/joint_states")
    pub = ros.publisher(JointState, f"{NODE}/joint_commands")
    got = sd.drive(states, pub, sd.joint_command(ARM_JOINTS, TARGET), 12)  # 3 s simulated
    last = got[-1]
    q = np.array(last.position)
    error = np.array(TARGET) - q
    gravity = REF.pick(pin.computeGeneralizedGravity(REF.model, REF.model.createData(), REF.q(ARM_JOINTS, q)), ARM_JOINTS)
    # At rest the PD carries the arm's weight: kp (q_cmd - q) = g(q).
    assert np.abs(np.array(last.velocity)).max() < 1e-6, last.velocity
    np.testing.assert_allclose(np.array(KP) * error, gravity, rtol=1e-6, atol=1e-6)
    assert abs(error[1]) > 1e-3, error  # the shoulder visibly sags: gravity is in the loop
    # The published effort is the servo's, the same weight.
    np.testing.assert_allclose(last.effort, gravity, rtol=1e-6, atol=1e-6)


def test_lockstep_closed_loop_runs_are_bit_identical_one_step_per_command(ros, sim):
    states = ros.collector(JointState, "/joint_states")
    pub = ros.publisher(JointState, f"{NODE}/joint_commands")

    def controller(state):
        # A deterministic feedback law: the next target from the last joint state.
        if state is None:
            return sd.joint_command(ARM_JOINTS, TARGET)
        q, v = np.array(state.position), np.array(state.velocity)
        return sd.joint_command(ARM_JOINTS, np.array(TARGET) - 0.5 * q - 0.05 * v, -0.1 * v)

    runs = []
    for _ in range(2):
        reset(ros)
        runs.append(sd.drive(states, pub, controller, 15))
    a, b = runs
    assert [m.position for m in a] == [m.position for m in b]
    assert [m.velocity for m in a] == [m.velocity for m in b]
    assert [m.effort for m in a] == [m.effort for m in b]
    for run in runs:
        steps = np.diff([sd.stamp_ns(m) for m in run])
        assert (steps == STEPS * DT_NS).all(), steps
    # Nothing advances without a command.
    states.clear()
    ros.spin_for(0.5)
    assert not states.messages


def test_bad_joint_commands_are_dropped_and_counted(ros, sim):
    states = ros.collector(JointState, "/joint_states")
    pub = ros.publisher(JointState, f"{NODE}/joint_commands")
    topic = f"{NODE}/joint_commands"
    diagnostics = ros.collector(DiagnosticArray, "/diagnostics")
    before = sd.status_values(diagnostics.wait(timeout=sd.EVENT_S)[-1], "spatial_dynamics: dynamics")
    for bad in (sd.joint_command(["elbow"], [0.1]), sd.joint_command(ARM_JOINTS, [], [0.0] * 7), sd.joint_command(ARM_JOINTS, [math.nan] + [0.0] * 6)):
        pub.publish(bad)
    diagnostics.clear()

    def counted(m):
        values = sd.status_values(m, "spatial_dynamics: dynamics")
        return sd.dropped_count(values, topic) - sd.dropped_count(before, topic) == 3

    ros.spin_until(lambda: diagnostics.matching(counted), sd.EVENT_S)
    values = sd.status_values(diagnostics.matching(counted)[0], "spatial_dynamics: dynamics")
    kinds = [k for k in values if k.startswith(f"{topic} dropped: ")]
    assert any("unknown joint" in k for k in kinds) and any("position has N values" in k for k in kinds), kinds
    assert not states.messages, "a refused command must not step"
