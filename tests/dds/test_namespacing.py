"""Names: `-r __ns:=/robot1` puts the node, its services, parameters and relative topics under
/robot1; `-r __node:=NAME` renames it; `-r FROM:=TO` remaps topics (also private `~/...` ones),
`-r NODE:FROM:=TO` only on node NODE. Two nodes run side by side; no node has the default name
here.
"""

import pytest
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.msg import JointDynamics
from spatial_dynamics_msgs.srv import DescribeModel, InverseDynamics
from std_msgs.msg import String

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

Q = [0.2, -0.4, 0.6, -0.8, 1.0, -1.2, 1.4]


@pytest.fixture(scope="module")
def both(module_nodes, ros, workdir):
    params = workdir / "ns.yaml"
    params.write_text("/robot1/spatial_dynamics:\n  ros__parameters:\n    method: crba\n")
    # Rules prefixed NODE: apply to that node only (name rules: its name after __node).
    a = module_nodes.start("-r", "__ns:=/robot1", "--params-file", params, "-r", "spatial_dynamics:~/acceleration:=/robot1/acc",
                           "-r", "dyn2:~/gravity_effort:=/never", label="robot1")
    b = module_nodes.start(
        "-r", "__node:=dyn2", "-r", "joint_states:=/arm/joint_states", "-r", "dyn2:~/gravity_effort:=/arm/gravity",
        "-r", "spatial_dynamics:~/acceleration:=/never", label="dyn2"
    )
    ros.wait_for_service(DescribeModel, "/robot1/spatial_dynamics/describe_model")
    ros.wait_for_service(DescribeModel, "/dyn2/describe_model")
    return a, b


def answered(ros, in_topic, out, timeout=sd.EVENT_S):
    """Publishes the arm's joint state on `in_topic`, a fresh stamp each time, until `out` (a
    collector) receives a message stamped like one of them (a writer matches a new reader a
    moment after the reader sees it); returns that message."""
    out.wait_publisher()
    pub = ros.publisher(JointState, in_topic, sd.qos_reliable(10))
    sent = []

    def publish():
        m = JointState(name=ARM_JOINTS, position=Q)
        m.header.stamp = sd.fresh_stamp()
        sent.append(m)
        pub.publish(m)

    return ros.exchange(publish, out, lambda m: any(sd.stamp_eq(m.header.stamp, s.header.stamp) for s in sent), timeout=timeout)


def gravity_roundtrip(ros, ref, in_topic, out_topic, timeout=sd.EVENT_S):
    got = answered(ros, in_topic, ros.collector(JointState, out_topic), timeout)
    assert_close(got.effort, ref.pick(ref.gravity(ref.q(ARM_JOINTS, Q)), ARM_JOINTS), f"{out_topic}")
    return got


def test_services_under_the_namespace_and_the_new_name(both, ros, ref):
    for prefix in ("/robot1/spatial_dynamics", "/dyn2"):
        resp = ros.call(InverseDynamics, f"{prefix}/inverse_dynamics", InverseDynamics.Request(name=ARM_JOINTS, position=Q))
        assert resp.success, resp.message
        assert_close(resp.effort, ref.pick(ref.gravity(ref.q(ARM_JOINTS, Q)), ARM_JOINTS), prefix)
    leaves = ("inverse_dynamics", "forward_dynamics", "mass_matrix", "describe_model", "get_parameters", "set_parameters")

    def services_of(name, namespace):
        try:
            return {n for n, _ in ros.node.get_service_names_and_types_by_node(name, namespace)}
        except _rclpy.NodeNameNonExistentError:  # not in our graph yet
            return set()

    def graph():
        return services_of("spatial_dynamics", "/robot1"), services_of("dyn2", "/")

    def complete():
        robot1, dyn2 = graph()
        return all(f"/robot1/spatial_dynamics/{n}" in robot1 and f"/dyn2/{n}" in dyn2 for n in leaves)

    ros.spin_until(complete, 10.0)  # the graph fills in as each service's endpoints are discovered
    robot1, dyn2 = graph()
    for name in leaves:
        assert f"/robot1/spatial_dynamics/{name}" in robot1, sorted(robot1)
        assert f"/dyn2/{name}" in dyn2, sorted(dyn2)
    # Nobody serves the default names.
    ros.spin_for(0.3)
    assert not ros.client(DescribeModel, "/spatial_dynamics/describe_model").service_is_ready()
    assert not ros.client(InverseDynamics, "/spatial_dynamics/inverse_dynamics").service_is_ready()


def test_node_names_in_the_graph(both, ros):
    assert ros.spin_until(
        lambda: {("spatial_dynamics", "/robot1"), ("dyn2", "/")} <= set(ros.node.get_node_names_and_namespaces()), 5.0
    ), ros.node.get_node_names_and_namespaces()


def test_params_file_entry_for_the_namespaced_node(both, ros):
    r = ros.call(DescribeModel, "/robot1/spatial_dynamics/describe_model", DescribeModel.Request())
    assert r.method == "crba"
    assert ros.get_parameters(["method"], node="/robot1/spatial_dynamics") == {"method": "crba"}
    assert ros.get_parameters(["method"], node="/dyn2") == {"method": "auto"}


def test_relative_topics_under_the_namespace(both, ros, ref):
    gravity_roundtrip(ros, ref, "/robot1/joint_states", "/robot1/spatial_dynamics/gravity_effort")


def test_a_rule_for_the_node_by_name(both, ros):
    answered(ros, "/robot1/joint_states", ros.collector(JointDynamics, "/robot1/acc"))


def test_remapped_input_and_output(both, ros, ref):
    gravity_roundtrip(ros, ref, "/arm/joint_states", "/arm/gravity")
    # Not remapped: dyn2's acceleration of the same input is at /dyn2/acceleration.
    answered(ros, "/arm/joint_states", ros.collector(JointDynamics, "/dyn2/acceleration"))
    # dyn2 does not listen on /joint_states: its counters only know /arm/joint_states.
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    report = diag.wait(1, sd.EVENT_S, lambda m: sd.status_values(m, "dyn2: dynamics") is not None)[0]
    values = sd.status_values(report, "dyn2: dynamics")
    assert int(values["/arm/joint_states received"]) >= 2
    assert not any(k.startswith("/joint_states") for k in values), values
    assert "/arm/gravity published" in values


def test_plain_joint_states_reaches_neither_node(both, ros):
    outs = [ros.collector(JointState, t) for t in ("/robot1/spatial_dynamics/gravity_effort", "/arm/gravity")]
    for out in outs:
        out.wait_publisher()
    pub = ros.publisher(JointState, "/joint_states", sd.qos_reliable(10), wait=False)
    stamps = []
    for _ in range(5):
        m = JointState(name=ARM_JOINTS, position=Q)
        m.header.stamp = sd.fresh_stamp()
        stamps.append(m.header.stamp)
        pub.publish(m)
        ros.spin_for(0.1)
    ros.spin_for(0.5)
    for out in outs:
        assert not out.matching(lambda m: any(sd.stamp_eq(m.header.stamp, s) for s in stamps)), out.topic
    assert pub.get_subscription_count() == 0


def test_robot_description_topic_under_the_namespace(both, ros):
    pub = ros.node.create_publisher(String, "/robot1/robot_description", sd.QOS_LATCHED)
    try:
        pub.publish(String(data=sd.PARTICLE_URDF.read_text()))

        def loaded():
            r = ros.call(DescribeModel, "/robot1/spatial_dynamics/describe_model", DescribeModel.Request())
            return "particle" in r.message

        assert ros.spin_until(loaded, sd.EVENT_S)
        r = ros.call(DescribeModel, "/dyn2/describe_model", DescribeModel.Request())
        assert "sd_arm7" in r.message, "dyn2 listens on /robot_description, not /robot1/robot_description"
    finally:
        ros.node.destroy_publisher(pub)
