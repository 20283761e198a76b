"""Bad service requests beyond test_services_arm.py's list: empty requests, huge arrays (a
million names, a million positions), and a client flooding bad requests while another client
(its own rclpy context: another DDS participant) is served correctly at the same time.

Each bad request is answered success=false with a message naming the problem and empty result
arrays; the answers that follow are right (checked against Pinocchio).
"""

import os
import time

import numpy as np
import pytest
from spatial_dynamics_msgs.srv import DescribeModel, ForwardDynamics, InverseDynamics, MassMatrix

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

ID = "/spatial_dynamics/inverse_dynamics"
FD = "/spatial_dynamics/forward_dynamics"
MM = "/spatial_dynamics/mass_matrix"
DM = "/spatial_dynamics/describe_model"
Q0 = [0.1, -0.2, 0.3, -0.4, 0.5, -0.6, 0.7]
MILLION = 1_000_000


@pytest.fixture(scope="module")
def other(arm):
    """A second client: its own rclpy context and node (another DDS participant)."""
    session = sd.RosSession(int(os.environ["ROS_DOMAIN_ID"]), "dds_test_other_client")
    session.wait_for_service(DescribeModel, DM)
    yield session
    session.close()


def id_good(session, ref, q=Q0):
    resp = session.call(InverseDynamics, ID, InverseDynamics.Request(name=ARM_JOINTS, position=list(q)))
    assert resp.success, resp.message
    zero = np.zeros(7)
    assert_close(resp.effort, ref.pick(ref.rnea(ref.q(ARM_JOINTS, q), zero, zero), ARM_JOINTS), "ID")


def refused(resp, words, arrays):
    assert resp.success is False, f"accepted: {str(resp)[:300]}"
    for word in words:
        assert word in resp.message, f"the reason {resp.message[:300]!r} does not name {word!r}"
    for array in arrays:
        assert len(getattr(resp, array)) == 0, f"{array} not empty on failure"
    # A reason is a sentence, not an echo of a huge request.
    assert len(resp.message) < 2000, f"reason of {len(resp.message)} characters"


EMPTY = {
    "id": (InverseDynamics, ID, ["position has 0 values for 7 names"], ("name", "effort")),
    "fd": (ForwardDynamics, FD, ["position has 0 values for 7 names"], ("name", "acceleration")),
    "mm": (MassMatrix, MM, ["position has 0 values for 7 names"], ("name", "matrix")),
}


@pytest.mark.parametrize("case", list(EMPTY))
def test_an_empty_request_is_refused_with_a_reason(arm, ros, ref, case):
    srv, name, words, arrays = EMPTY[case]
    refused(ros.call(srv, name, srv.Request()), words, arrays)
    id_good(ros, ref)


HUGE = {
    # A million unknown names: the first one is named.
    "id_million_unknown_names": (InverseDynamics, ID, lambda: dict(name=[f"j{i}" for i in range(MILLION)], position=[0.0] * MILLION), ["unknown joint 'j0'"]),
    # A million positions for seven names.
    "id_million_positions": (InverseDynamics, ID, lambda: dict(name=ARM_JOINTS, position=[0.0] * MILLION), ["position has 1000000 values for 7 names"]),
    # The seven joints, then a million repeats of joint1.
    "fd_million_duplicates": (ForwardDynamics, FD, lambda: dict(name=ARM_JOINTS + ["joint1"] * MILLION, position=[0.0] * (MILLION + 7)), ["joint 'joint1' appears twice"]),
    "mm_million_positions": (MassMatrix, MM, lambda: dict(name=ARM_JOINTS, position=[0.1] * (MILLION)), ["position has 1000000 values"]),
}


@pytest.mark.parametrize("case", list(HUGE))
def test_a_huge_request_is_refused_with_a_short_reason(arm, ros, ref, case):
    srv, name, make, words = HUGE[case]
    start = time.monotonic()
    resp = ros.call(srv, name, srv.Request(**make()), timeout=30.0)
    took = time.monotonic() - start
    print(f"{case}: answered in {took:.2f} s")
    refused(resp, words, ())
    id_good(ros, ref)


def test_another_client_is_served_while_one_floods_bad_requests(arm, ros, other, ref):
    """Client A keeps 8 bad requests in flight at a time (within the service queue depth, 10, the
    ROS default: a client with more in flight may lose some, as with any ROS 2 service); between
    them client B's good requests are answered correctly, and every bad one is refused."""
    bad_kinds = [
        InverseDynamics.Request(name=ARM_JOINTS + ["elbow"], position=Q0 + [0.0]),
        InverseDynamics.Request(name=ARM_JOINTS, position=Q0[:3]),
        InverseDynamics.Request(name=ARM_JOINTS, position=Q0[:6] + [float("nan")]),
        InverseDynamics.Request(name=ARM_JOINTS, position=Q0, velocity=[1e200] * 7),
    ]
    client = ros.wait_for_service(InverseDynamics, ID)
    rng = np.random.default_rng(3)
    pending, refused_count, good = [], 0, 0
    for round_ in range(10):
        pending += [client.call_async(bad_kinds[(round_ + k) % len(bad_kinds)]) for k in range(8)]
        q = [float(x) for x in rng.uniform(-1, 1, 7)]
        id_good(other, ref, q)  # B, while A's requests are queued at the node
        good += 1
        ros.spin_until(lambda: all(f.done() for f in pending), sd.EVENT_S)
        for future in pending:
            assert future.done(), "a bad request went unanswered"
            resp = future.result()
            assert resp.success is False and resp.message, resp
            refused_count += 1
        pending = []
    assert (refused_count, good) == (80, 10)
    arm.assert_alive()
