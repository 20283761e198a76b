"""Latency of the node over DDS against an rclpy echo node, measured in the same run.

- service round trip: ~/inverse_dynamics (7-DOF arm) vs an rclpy server of the same type that
  answers at once with a fixed response;
- topic in → out: joint_states → ~/gravity_effort vs an rclpy node that republishes each
  JointState it receives;
- the node's own computation per message, from its /diagnostics ("compute mean (us)").

The probe and the echo node share one single-threaded executor in this process (the echo node's
callbacks run when the probe spins), so both paths pay the same client-side costs.

Run inside a private network namespace: launch_scripts/bench_ros_latency.sh
Prints a markdown table (p50 / p99 in microseconds).
"""
import os
import subprocess
import sys
import time

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from diagnostic_msgs.msg import DiagnosticArray
from spatial_dynamics_msgs.srv import InverseDynamics

N_CALLS = int(os.environ.get("BENCH_CALLS", "2000"))
NAMES = [f"joint{i}" for i in range(1, 8)]


class Echo(Node):
    """The reference: an rclpy node doing the least possible work."""

    def __init__(self):
        super().__init__("echo")
        self.create_service(InverseDynamics, "/echo/inverse_dynamics", self.answer)
        self.pub = self.create_publisher(JointState, "/echo/out", 10)
        self.create_subscription(JointState, "/echo/in", self.pub.publish, 10)

    def answer(self, request, response):
        response.success = True
        response.name = list(request.name)
        response.effort = [0.0] * len(request.name)
        return response


class Probe(Node):
    def __init__(self):
        super().__init__("latency_probe")
        self.arrivals = {}
        best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        for topic in ("/spatial_dynamics/gravity_effort", "/echo/out"):
            self.create_subscription(JointState, topic, self.arrived, best_effort)
        self.compute_us = []
        self.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics, 10)

    def arrived(self, msg):
        self.arrivals[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = time.perf_counter()

    def diagnostics(self, msg):
        for status in msg.status:
            for kv in status.values:
                if kv.key == "compute mean (us)":
                    self.compute_us.append(float(kv.value))


def percentiles(samples):
    a = np.array(samples) * 1e6
    return np.percentile(a, 50), np.percentile(a, 99)


def spin_until(executor, done, timeout):
    end = time.perf_counter() + timeout
    while not done() and time.perf_counter() < end:
        executor.spin_once(timeout_sec=0.01)
    return done()


def service_latency(executor, probe, name):
    client = probe.create_client(InverseDynamics, name)
    assert spin_until(executor, client.service_is_ready, 20), name
    rng = np.random.default_rng(1)
    samples = []
    for i in range(N_CALLS + 100):
        req = InverseDynamics.Request(name=NAMES, position=list(rng.uniform(-1, 1, 7)),
                                      velocity=list(rng.uniform(-1, 1, 7)), acceleration=list(rng.uniform(-1, 1, 7)))
        t0 = time.perf_counter()
        future = client.call_async(req)
        if not spin_until(executor, future.done, 5):
            raise RuntimeError(f"{name}: no answer")
        if i >= 100:
            samples.append(time.perf_counter() - t0)
        assert future.result().success, future.result().message
    return samples


def topic_latency(executor, probe, topic_in, period=0.002):
    pub = probe.create_publisher(JointState, topic_in, 10)
    spin_until(executor, lambda: False, 1.0)
    samples, lost = [], 0
    rng = np.random.default_rng(2)
    for i in range(N_CALLS + 100):
        msg = JointState(name=NAMES, position=list(rng.uniform(-1, 1, 7)), velocity=list(rng.uniform(-1, 1, 7)))
        msg.header.stamp.sec = 1000 + i
        key = (1000 + i, 0)
        t0 = time.perf_counter()
        pub.publish(msg)
        spin_until(executor, lambda: key in probe.arrivals, 1.0)
        if key in probe.arrivals:
            if i >= 100:
                samples.append(probe.arrivals[key] - t0)
        else:
            lost += 1
        spin_until(executor, lambda: False, period)
    probe.arrivals.clear()
    return samples, lost


def main():
    binary = os.environ.get("SPATIAL_DYNAMICS_BIN", os.path.join(os.path.dirname(__file__), "..", "target", "release", "spatial_dynamics"))
    node_proc = subprocess.Popen([binary, "node"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rclpy.init()
    echo, probe = Echo(), Probe()
    executor = SingleThreadedExecutor()
    executor.add_node(echo)
    executor.add_node(probe)
    try:
        rows = []
        for label, name in (("spatial_dynamics ~/inverse_dynamics", "/spatial_dynamics/inverse_dynamics"), ("rclpy echo service", "/echo/inverse_dynamics")):
            p50, p99 = percentiles(service_latency(executor, probe, name))
            rows.append((f"service round trip: {label}", p50, p99, ""))
        for label, topic in (("joint_states → spatial_dynamics ~/gravity_effort", "/joint_states"), ("rclpy echo node", "/echo/in")):
            samples, lost = topic_latency(executor, probe, topic)
            p50, p99 = percentiles(samples)
            rows.append((f"topic in → out: {label}", p50, p99, f"{lost} lost of {N_CALLS + 100}"))
        spin_until(executor, lambda: False, 1.5)
        compute = float(np.median(probe.compute_us)) if probe.compute_us else float("nan")
        print(f"\n{N_CALLS} samples each, loopback, 7-DOF arm (sd_arm7)\n")
        print("| path | p50 (µs) | p99 (µs) | notes |\n|---|---|---|---|")
        for label, p50, p99, note in rows:
            print(f"| {label} | {p50:.0f} | {p99:.0f} | {note} |")
        print(f"| node's own computation per joint_states message (gravity + forward dynamics), from /diagnostics | {compute:.1f} (median of 1 s means) | | |")
    finally:
        node_proc.terminate()
        node_proc.wait()
        executor.shutdown()
        echo.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
