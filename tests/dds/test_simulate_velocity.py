"""Simulate mode with velocity servos (command_interface: velocity) in lockstep: a commanded
joint rate is tracked. Without gravity the arm's weight asks nothing of the servos, so joint1
(the vertical base axis) turns at the commanded rate while the other joints' servos hold them
at zero rate; the position then advances at that rate, in simulated time from the stamps.
"""

import numpy as np
import pinocchio as pin
import pytest
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.srv import DescribeModel

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS

NODE = "/spatial_dynamics"
RATE = 0.5
STEPS = 200
REF = sd.PinRef(urdf_path=sd.DEFAULT_ARM_URDF)
_H = pin.crba(REF.model, REF.model.createData(), REF.q(ARM_JOINTS, [0.0] * 7))
# kd = 100 I per joint: a 10 ms time constant, h kd / I = 0.1 at sim_dt = 1 ms.
KD = [float(100.0 * _H[REF.joints[j].idx_v, REF.joints[j].idx_v]) for j in ARM_JOINTS]


@pytest.fixture(scope="module")
def sim(module_nodes, ros):
    node = module_nodes.start(
        "-p", "mode:=simulate", "-p", "command_interface:=velocity", "-p", f"servo_kd:={KD}",
        "-p", "gravity:=[0.0, 0.0, 0.0]", "-p", "step_mode:=on_command", "-p", f"steps_per_command:={STEPS}",
        label="velocity",
    )
    ros.wait_for_service(DescribeModel, f"{NODE}/describe_model")
    return node


def test_a_velocity_servo_tracks_the_commanded_rate(ros, sim):
    states = ros.collector(JointState, "/joint_states")
    pub = ros.publisher(JointState, f"{NODE}/joint_commands")
    rates = [RATE] + [0.0] * 6
    got = sd.drive(states, pub, sd.joint_command(ARM_JOINTS, [], rates), 10)  # 2 s simulated
    v = np.array(got[-1].velocity)
    # After 200 time constants the rate error left is what the coupling torques ask of kd.
    assert abs(v[0] - RATE) < 1e-3, v
    assert np.abs(v[1:]).max() < 1e-2, v
    dt = (sd.stamp_ns(got[-1]) - sd.stamp_ns(got[-2])) * 1e-9
    assert dt == pytest.approx(STEPS * 1e-3, abs=1e-12)
    advance = got[-1].position[0] - got[-2].position[0]
    assert advance == pytest.approx(RATE * dt, rel=2e-3), advance
