"""The handout's particle (config/models/particle.urdf, loaded by `-p urdf_file:=...`): a point mass
m = 1 kg on two massless prismatic joints x (world x) and z (world z, vertical). Closed forms:
    M = m I,   g(q) = [0, m g0],   tau = m qdd + [0, m g0],   qdd = (tau - [0, m g0]) / m
with g0 = 9.81 m/s^2, for every position and velocity.
"""

import numpy as np
import pytest
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics
from spatial_dynamics_msgs.srv import DescribeModel, ForwardDynamics, InverseDynamics, MassMatrix
from std_msgs.msg import Float64MultiArray

import sd_dds_support as sd
from sd_dds_support import assert_close

M, G0 = 1.0, 9.81
GRAV = {"x": 0.0, "z": M * G0}


@pytest.fixture(scope="module")
def particle(module_nodes, ros):
    node = module_nodes.start("-p", f"urdf_file:={sd.PARTICLE_URDF}", label="particle")
    ros.wait_for_service(DescribeModel, "/spatial_dynamics/describe_model")
    return node


def test_describe_particle(particle, ros):
    r = ros.call(DescribeModel, "/spatial_dynamics/describe_model", DescribeModel.Request())
    assert r.success, r.message
    assert "particle" in r.message
    assert list(r.joint_names) == ["x", "z"] and list(r.joint_types) == ["prismatic", "prismatic"]
    assert list(r.position_lower) == [-100.0, -100.0] and list(r.position_upper) == [100.0, 100.0]
    assert list(r.velocity_limit) == [10.0, 10.0] and list(r.effort_limit) == [100.0, 100.0]
    assert (r.nq, r.nv) == (2, 2)
    assert list(r.link_names) == ["world", "slider_x", "particle"]


@pytest.mark.parametrize("names", [["x", "z"], ["z", "x"]])
def test_inverse_dynamics_closed_form(particle, ros, names):
    rng = np.random.default_rng(len(names[0]) + ord(names[0]))
    for _ in range(5):
        q, v, a = (list(map(float, rng.uniform(-50, 50, 2))) for _ in range(3))
        resp = ros.call(InverseDynamics, "/spatial_dynamics/inverse_dynamics",
                        InverseDynamics.Request(name=names, position=q, velocity=v, acceleration=a))
        assert resp.success, resp.message
        assert list(resp.name) == names
        assert_close(resp.effort, [M * a[i] + GRAV[n] for i, n in enumerate(names)], "tau = m qdd + [0, m g]")


@pytest.mark.parametrize("method", ["", "aba", "crba", "rnea_columns"])
def test_forward_dynamics_closed_form(particle, ros, method):
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v, tau = (list(map(float, rng.uniform(-50, 50, 2))) for _ in range(3))
        resp = ros.call(ForwardDynamics, "/spatial_dynamics/forward_dynamics",
                        ForwardDynamics.Request(name=["z", "x"], position=q, velocity=v, effort=tau, method=method))
        assert resp.success, resp.message
        assert_close(resp.acceleration, [(tau[0] - M * G0) / M, tau[1] / M], f"qdd [{method}]")
    resp = ros.call(ForwardDynamics, "/spatial_dynamics/forward_dynamics", ForwardDynamics.Request(position=[1.0, 2.0], method=method))
    assert resp.success and list(resp.name) == ["x", "z"]
    assert_close(resp.acceleration, [0.0, -G0], "free fall")


def test_mass_matrix_closed_form(particle, ros):
    for q in ([0.0, 0.0], [12.5, -40.0]):
        resp = ros.call(MassMatrix, "/spatial_dynamics/mass_matrix", MassMatrix.Request(name=["z", "x"], position=q))
        assert resp.success, resp.message
        assert_close(resp.matrix, [M, 0.0, 0.0, M], "M = m I")


def test_gravity_effort_and_acceleration_topics_closed_form(particle, ros):
    gravity = ros.collector(JointState, "/spatial_dynamics/gravity_effort")
    accel = ros.collector(JointDynamics, "/spatial_dynamics/acceleration")
    gravity.wait_publisher()
    accel.wait_publisher()
    js = ros.publisher(JointState, "/joint_states", sd.qos_best_effort(10))
    commands = ros.publisher(Float64MultiArray, "/spatial_dynamics/commands", sd.qos_reliable(10))
    command = [3.0, 20.0]  # x, z (command_joints default: model order)
    sent = []

    def publish():
        commands.publish(Float64MultiArray(data=command))
        ros.spin_for(0.02)
        m = JointState(name=["z", "x"], position=[5.0, -5.0], velocity=[1.0, 2.0])
        m.header.stamp = sd.fresh_stamp()
        sent.append(m)
        js.publish(m)

    got = ros.exchange(publish, accel, lambda m: any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent) and list(m.effort) == [20.0, 3.0])
    assert list(got.name) == ["z", "x"]
    assert_close(got.acceleration, [(20.0 - M * G0) / M, 3.0 / M], "qdd under the command")
    g = gravity.wait(1, sd.EVENT_S, lambda m: sd.stamp_eq(m.header.stamp, got.header.stamp))[0]
    assert_close(g.effort, [M * G0, 0.0], "gravity effort [z, x]")
