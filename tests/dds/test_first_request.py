"""A fresh client's first request (issue 22, item 6): each of many clients, made anew, calls a
service once, the moment it sees the service, as `ros2 service call` does; none may be lost.

Each client comes on a fresh rclpy node, so its request writer and response reader are new
endpoints that the node must discover (SEDP) anew. The client sees the service as soon as its own
side has matched the node's endpoints, which is often before the node has processed the client's
announcements: its request then reaches the node's reader before that reader knows the writer.
The reliability protocol must still deliver it (the node's reader, once matched, asks the
client's writer for what it holds).
"""

import time

import rclpy
from spatial_dynamics_msgs.srv import DescribeModel

import sd_dds_support as sd

DM = f"{sd.NODE}/describe_model"
CLIENTS = 100
CALL_TIMEOUT_S = 3.0


def test_fresh_clients_first_request_answered(arm, ros):
    lost = []
    for i in range(CLIENTS):
        node = rclpy.create_node(f"first_request_{i}", context=ros.context)
        ros.executor.add_node(node)
        try:
            client = node.create_client(DescribeModel, DM)
            # Poll tightly (not wait_for_service's 0.25 s sleeps): call the instant it is ready.
            end = time.monotonic() + 10.0
            while not client.service_is_ready():
                assert time.monotonic() < end, f"client {i}: {DM} not available within 10 s"
                ros.executor.spin_once(timeout_sec=0.002)
            future = client.call_async(DescribeModel.Request())
            if ros.spin_until(future.done, CALL_TIMEOUT_S):
                assert future.result().success, future.result().message
            else:
                lost.append(i)
                client.remove_pending_request(future)
            node.destroy_client(client)
        finally:
            ros.executor.remove_node(node)
            node.destroy_node()
    assert not lost, f"{len(lost)} of {CLIENTS} first requests got no answer within {CALL_TIMEOUT_S} s: clients {lost}"
