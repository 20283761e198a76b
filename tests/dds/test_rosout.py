"""The node's log on /rosout, as an rclcpp node logs: rcl_interfaces/msg/Log with rcl's logger
name (namespace and name joined by dots, no leading slash), rcutils' levels (INFO 20, WARN 30),
where the line was logged, a wall-clock stamp; rcl's rosout QoS (reliable, transient local,
lifespan 10 s); `--log-level LEVEL` and `--log-level LOGGER:=LEVEL` honoured.

The subscriber uses rclpy's own rosout profile (depth 1000, transient local), made before the node
starts, so it sees the start-up lines. Lines of one node arrive in order (one reliable writer):
once a later line has arrived, the absence of an earlier one is final.
"""

import time

import pytest
from rcl_interfaces.msg import Log
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy, qos_profile_rosout_default
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.srv import DescribeModel

import sd_dds_support as sd

STARTED = "serving robot 'sd_arm7'"
DROPPED = "dropped a message on "


def rosout(ros):
    return ros.collector(Log, "/rosout", qos_profile_rosout_default)


def lines(log, name, level=None, text=""):
    return log.matching(lambda m: m.name == name and (level is None or m.level == level) and text in m.msg)


def provoke_warning(ros, log, name, topic="/joint_states"):
    """Publishes a joint state naming an unknown joint until the node's WARN about it arrives."""
    pub = ros.publisher(JointState, topic, sd.qos_reliable(10))
    return ros.exchange(
        lambda: pub.publish(JointState(name=["no_such_joint"], position=[0.0])),
        log,
        lambda m: m.name == name and m.level == Log.WARN and f"{DROPPED}{topic}:" in m.msg,
        timeout=sd.EVENT_S,
    )


def test_start_up_info_and_bad_input_warning_on_rosout(nodes, ros):
    log = rosout(ros)
    nodes.start(label="rosout")
    info = log.wait(1, sd.EVENT_S, lambda m: m.name == "spatial_dynamics" and STARTED in m.msg)[0]
    assert info.level == Log.INFO == 20
    assert info.file.endswith("src/node/mod.rs") and info.line > 0, info
    assert info.function.endswith("node::serve"), info
    assert abs(info.stamp.sec + info.stamp.nanosec * 1e-9 - time.time()) < 60.0, info.stamp
    warn = provoke_warning(ros, log, "spatial_dynamics")
    assert warn.level == Log.WARN == 30
    assert "no_such_joint" in warn.msg and warn.file.endswith("src/node/health.rs"), warn
    # The publisher has rcl's rosout QoS (history depth is not part of discovery). The graph names
    # a writer's node once that node's participant entities (ros_discovery_info) have arrived, which
    # may be after the writer's first lines: the graph is waited for, as `ros2 topic info` would be.
    def ours():
        return [i for i in ros.node.get_publishers_info_by_topic("/rosout") if i.node_name == "spatial_dynamics"]

    ros.spin_until(lambda: len(ours()) == 1, sd.EVENT_S)
    infos = ours()
    assert len(infos) == 1, infos
    qos = infos[0].qos_profile
    assert qos.reliability == ReliabilityPolicy.RELIABLE and qos.durability == DurabilityPolicy.TRANSIENT_LOCAL, qos
    assert qos.lifespan.nanoseconds == 10_000_000_000, qos


@pytest.mark.parametrize(
    "ns, level_args",
    [("/", ["--log-level", "warn"]), ("/robot1", ["--log-level", "robot1.spatial_dynamics:=WARN"]),
     ("/robot1", ["--log-level", "debug", "--log-level", "robot1:=warn"])],
    ids=["default_level", "node_logger", "ancestor_logger"],
)
def test_log_level_warn_suppresses_info(nodes, ros, ns, level_args):
    name = "spatial_dynamics" if ns == "/" else f"{ns.strip('/').replace('/', '.')}.spatial_dynamics"
    prefix = f"{ns.rstrip('/')}/spatial_dynamics"
    log = rosout(ros)
    node = nodes.start("-r", f"__ns:={ns}", *level_args, label="quiet")
    ros.wait_for_service(DescribeModel, f"{prefix}/describe_model")
    provoke_warning(ros, log, name, topic=f"{ns.rstrip('/')}/joint_states")
    # The WARN came after the start-up INFO would have: none was published, none printed.
    assert not lines(log, name, Log.INFO), lines(log, name, Log.INFO)
    assert not lines(log, name, Log.DEBUG)
    assert STARTED not in node.log() and DROPPED in node.log(), node.log()[-2000:]


def test_default_level_is_info_and_the_namespaced_name_is_dotted(nodes, ros):
    log = rosout(ros)
    nodes.start("-r", "__ns:=/robot1", label="robot1")
    info = log.wait(1, sd.EVENT_S, lambda m: STARTED in m.msg and m.name.endswith("spatial_dynamics"))[0]
    assert info.name == "robot1.spatial_dynamics" and info.level == Log.INFO, info


def test_unknown_log_level_is_refused_at_start(nodes):
    node = nodes.start("--log-level", "loud", label="loud", expect_exit=True)
    assert node.wait_exit(10.0) != 0
    assert "unknown severity 'loud'" in node.log(), node.describe()
