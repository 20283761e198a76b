"""Conventions that users' tools assume of a node: /diagnostics as diagnostic_updater publishes it
(status "<node name>: <task>", no leading slash, hardware_id set); only simulate mode publishes
joint_states, /clock and ~/base_state (a serve-mode node must not show up as a second source of
them, e.g. beside a robot driver); a robot description arriving on the topic while the
robot_description or urdf_file parameter is set is logged once as ignored, saying why.
"""

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Log
from rclpy.qos import qos_profile_rosout_default
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.srv import DescribeModel
from std_msgs.msg import String

import sd_dds_support as sd

SIM_TOPICS = ("/joint_states", "/clock", "/spatial_dynamics/base_state")


def publishers_of(ros, topic, node="spatial_dynamics"):
    return [i for i in ros.node.get_publishers_info_by_topic(topic) if i.node_name == node]


def test_diagnostics_as_diagnostic_updater_publishes_them(nodes, ros):
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    nodes.start(label="diag")
    report = diag.wait(1, sd.EVENT_S, lambda m: any(s.name == "spatial_dynamics: dynamics" for s in m.status))[0]
    status = next(s for s in report.status if s.name == "spatial_dynamics: dynamics")
    assert status.hardware_id == "sd_arm7", status
    assert not any(s.name.startswith("/") for m in diag.messages for s in m.status), [s.name for m in diag.messages for s in m.status]


def test_serve_mode_publishes_no_joint_states_clock_or_base_state(nodes, ros):
    nodes.start("-p", "floating_base:=true", label="serve")
    ros.wait_for_service(DescribeModel, f"{sd.NODE}/describe_model")
    # The node's publishers are known once its outputs are: then the simulation topics have none.
    assert ros.spin_until(lambda: publishers_of(ros, "/spatial_dynamics/gravity_effort") and publishers_of(ros, "/diagnostics"), sd.EVENT_S)
    for topic in SIM_TOPICS:
        assert not publishers_of(ros, topic), (topic, publishers_of(ros, topic))


def test_simulate_mode_keeps_its_publishers(nodes, ros):
    nodes.start("-p", "mode:=simulate", "-p", "floating_base:=true", label="simulate")
    for topic in SIM_TOPICS:
        assert ros.spin_until(lambda: publishers_of(ros, topic), sd.EVENT_S), f"no publisher of the node on {topic}"


@pytest.mark.parametrize("source", ["urdf_file", "robot_description"])
def test_topic_description_ignored_while_a_parameter_is_set_is_logged_once(nodes, ros, latched, tmp_path, source):
    params = tmp_path / "p.yaml"
    value = str(sd.PARTICLE_URDF) if source == "urdf_file" else sd.PARTICLE_URDF.read_text()
    params.write_text(f"/**:\n  ros__parameters:\n    {source}: {sd.yaml_string(value)}\n")
    log = ros.collector(Log, "/rosout", qos_profile_rosout_default)
    nodes.start("--params-file", params, label=f"ignored_{source}")
    pub = latched(subscribed=True)
    ignored = lambda m: m.name == "spatial_dynamics" and "ignoring the robot description on /robot_description" in m.msg
    pub.publish(String(data=sd.MIMIC_GRIPPER_URDF.read_text()))
    line = log.wait(1, sd.EVENT_S, ignored)[0]
    why = "urdf_file is set" if source == "urdf_file" else "the robot_description parameter is set"
    assert why in line.msg and line.level == Log.INFO, line
    # A second description: counted on /diagnostics, and not logged again. A WARN provoked after
    # it arrives after any line about it (one writer, in order).
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    pub.publish(String(data=sd.LAMP_URDF.read_text()))
    diag.wait(1, sd.EVENT_S, lambda m: int((sd.status_values(m, "spatial_dynamics: dynamics") or {}).get("/robot_description received", 0)) >= 2)
    js = ros.publisher(JointState, "/joint_states", sd.qos_reliable(10))
    ros.exchange(lambda: js.publish(JointState(name=["no_such_joint"], position=[0.0])), log,
                 lambda m: m.name == "spatial_dynamics" and m.level == Log.WARN, timeout=sd.EVENT_S)
    assert len(log.matching(ignored)) == 1, [m.msg for m in log.matching(ignored)]
    r = ros.call(DescribeModel, f"{sd.NODE}/describe_model", DescribeModel.Request())
    assert "particle" in r.message, r.message
