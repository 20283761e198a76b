"""pytest set-up for the DDS tests: the real `spatial_dynamics node` binary against rclpy.

* Runs only inside a private network namespace (loopback only): use
  ``launch_scripts/netns_exec.sh .venv/bin/python -m pytest -q tests/dds``.
* Each pytest process uses its own ROS_DOMAIN_ID (from its pid, 1..100; override with
  SD_TEST_DOMAIN_ID), set for rclpy and passed to every node it starts.
* The binary: $SPATIAL_DYNAMICS_BIN or <repo>/target/release/spatial_dynamics; missing = failure.
* Fixtures: ``ros`` (one rclpy context + node per module), ``module_nodes`` / ``nodes`` (start
  the node as a subprocess for the module / the test; stopped with SIGINT, then SIGKILL),
  ``workdir`` (a temporary directory per module for parameter files), ``arm`` (a node on the
  default arm for the module), ``ref`` (Pinocchio on the default arm), ``latched`` (publishers
  on /robot_description). The log of every node
  still running when a test fails is attached to the failure report, and a test after which a
  node has died unexpectedly fails.
"""

from __future__ import annotations

import os
import socket

import pytest
from spatial_dynamics_msgs.srv import DescribeModel
from std_msgs.msg import String

import sd_dds_support as sd


def _domain_id() -> int:
    env = os.environ.get("SD_TEST_DOMAIN_ID")
    return int(env) if env else os.getpid() % 100 + 1


DOMAIN_ID = _domain_id()


def pytest_configure(config):
    interfaces = sorted(name for _, name in socket.if_nameindex())
    if interfaces != ["lo"]:
        pytest.exit(
            "the DDS tests must run in a private network namespace with only loopback "
            f"(this one has {interfaces}): launch_scripts/netns_exec.sh .venv/bin/python -m pytest tests/dds",
            returncode=4,
        )
    os.environ["ROS_DOMAIN_ID"] = str(DOMAIN_ID)


def pytest_report_header(config):
    binary = sd.binary_path()
    return [
        f"spatial_dynamics binary: {binary}{'' if binary.is_file() else '  (MISSING)'}",
        f"ROS_DOMAIN_ID={DOMAIN_ID}",
    ]


def pytest_terminal_summary(terminalreporter):
    # In the summary, not the header: `pytest -q` (as run_tests.sh runs) prints no header.
    terminalreporter.write_line(f"ROS 2 under test: {sd.ros_versions()}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.failed:
        for node in list(sd.LIVE_NODES):
            report.sections.append((f"spatial_dynamics node {node.label}", node.describe()))


@pytest.fixture(scope="session")
def sd_binary():
    binary = sd.binary_path()
    if not binary.is_file():
        pytest.fail(f"the spatial_dynamics binary is missing: {binary} (build it, or set SPATIAL_DYNAMICS_BIN)")
    return binary


class NodeLauncher:
    """Starts `spatial_dynamics node --ros-args ...` processes; stops them all on close()."""

    def __init__(self, binary, log_dir, prefix, session):
        self.session = session
        self.binary = binary
        self.log_dir = log_dir
        self.prefix = prefix
        self.started = []

    def start(self, *ros_args, env=None, label=None, expect_exit=False, raw_args=None):
        """Starts the node with `--ros-args ROS_ARGS` (or exactly `raw_args`)."""
        n = len(self.started)
        label = label or f"{self.prefix}-{n}"
        full_env = dict(os.environ)
        full_env["ROS_DOMAIN_ID"] = str(DOMAIN_ID)
        full_env.update(env or {})
        args = list(raw_args) if raw_args is not None else (["--ros-args", *ros_args] if ros_args else [])
        before = self.session.rosout_writers()
        node = sd.NodeProcess(self.binary, args, full_env, self.log_dir / f"{label}.log", label, expect_exit)
        self.started.append(node)
        if not expect_exit:
            if not self.session.wait_new_node(before):
                raise AssertionError(f"the node was not discovered within {sd.EVENT_S} s:\n{node.describe()}")
        return node

    def close(self):
        dead = [n for n in self.started if not n.expect_exit and n.poll() is not None and n in sd.LIVE_NODES]
        reports = [n.describe() for n in dead]
        for node in self.started:
            node.stop()
        if reports:
            pytest.fail("node(s) had died before they were stopped:\n" + "\n".join(reports))


@pytest.fixture(scope="module")
def module_nodes(sd_binary, tmp_path_factory, request, ros):
    launcher = NodeLauncher(sd_binary, tmp_path_factory.mktemp("node_logs"), request.module.__name__, ros)
    yield launcher
    launcher.close()


@pytest.fixture
def nodes(sd_binary, tmp_path, request, ros):
    launcher = NodeLauncher(sd_binary, tmp_path, request.node.name.replace("/", "_")[:60], ros)
    yield launcher
    launcher.close()


@pytest.fixture(scope="module")
def ros(request):
    session = sd.RosSession(DOMAIN_ID, f"dds_test_{request.module.__name__.replace('.', '_')}")
    yield session
    session.close()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("work")


@pytest.fixture(autouse=True)
def _nodes_survive():
    """A node that dies during a test (other than one expected to exit) fails that test."""
    yield
    dead = [n for n in sd.LIVE_NODES if not n.expect_exit and n.poll() is not None]
    if dead:
        pytest.fail("node(s) died during this test:\n" + "\n".join(n.describe() for n in dead))


@pytest.fixture(scope="module")
def arm(module_nodes, ros):
    """A node on the embedded default arm, for the module, with its services up."""
    node = module_nodes.start(label="arm")
    ros.wait_for_service(DescribeModel, f"{sd.NODE}/describe_model")
    return node


@pytest.fixture(scope="module")
def ref():
    """Pinocchio on the embedded default arm (a module may override it for another robot)."""
    return sd.PinRef(sd.DEFAULT_ARM_URDF)


@pytest.fixture
def latched(ros):
    """Makes transient-local publishers on /robot_description (``make(subscribed=True)`` also
    waits until the node subscribes); destroyed after the test."""
    pubs = []

    def make(subscribed=False):
        pub = ros.node.create_publisher(String, "/robot_description", sd.QOS_LATCHED)
        pubs.append(pub)
        if subscribed:
            assert ros.spin_until(lambda: pub.get_subscription_count() > 0, sd.EVENT_S), "robot_description not subscribed"
        return pub

    yield make
    for pub in pubs:
        ros.node.destroy_publisher(pub)
