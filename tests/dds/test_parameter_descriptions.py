"""Every parameter declared as rclcpp declares one: rclpy's describe_parameters gives each a
description, its type, read_only where the value only acts when the simulation is built, and a
range where the value is one number; a read-only parameter refuses a new value; a parameter file's
parameters that the node does not have are ignored with one warning (as rclcpp ignores them) and
the node serves.

The expected names, types and read-only set below are the node's documented parameter table
(src/node/params.rs), written out here on purpose: a parameter added or dropped without it shows.
"""

import math

from rcl_interfaces.msg import Log
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_rosout_default
from spatial_dynamics_msgs.srv import DescribeModel

import sd_dds_support as sd

T = Parameter.Type
TYPES = {
    "robot_description": T.STRING, "urdf_file": T.STRING, "floating_base": T.BOOL, "ignore_mimic": T.BOOL,
    "locked_joints": T.STRING_ARRAY, "root_link": T.STRING, "tip_links": T.STRING_ARRAY, "prune_massless": T.BOOL,
    "gravity": T.DOUBLE_ARRAY, "method": T.STRING, "command_joints": T.STRING_ARRAY, "use_sim_time": T.BOOL,
    "max_stamp_age": T.DOUBLE, "future_stamp_tolerance": T.DOUBLE, "mode": T.STRING, "publish_rate": T.DOUBLE,
    "sim_dt": T.DOUBLE, "integrator": T.STRING, "real_time_factor": T.DOUBLE, "publish_clock": T.BOOL,
    "command_timeout": T.DOUBLE, "passive": T.STRING_ARRAY, "initial_positions": T.STRING_ARRAY,
    "ground_contacts": T.STRING_ARRAY, "ground_height": T.DOUBLE, "ground_stiffness": T.DOUBLE,
    "ground_damping": T.DOUBLE, "ground_friction": T.DOUBLE, "command_interface": T.STRING,
    "servo_kp": T.DOUBLE_ARRAY, "servo_kd": T.DOUBLE_ARRAY, "step_mode": T.STRING, "steps_per_command": T.INTEGER,
    "publish_tf": T.BOOL,
}
READ_ONLY = {
    "mode", "publish_rate", "sim_dt", "integrator", "real_time_factor", "command_timeout", "passive",
    "initial_positions", "ground_contacts", "ground_height", "ground_stiffness", "ground_damping", "ground_friction",
    "command_interface", "servo_kp", "servo_kd", "step_mode", "steps_per_command", "publish_tf",
}
# Numbers with a range of their own (from, to): the node's timers hold periods of 1000 s to 1 µs.
BOUNDED = {"publish_rate": (1e-3, 1e6)}
# Integer parameters' ranges (inclusive; step 0: any), as params.rs checks them.
INTEGER_RANGES = {"steps_per_command": (1, 1_000_000, 0)}
# Numbers that must be > 0, >= 0, or only finite: the lower bound of their range.
POSITIVE = {"sim_dt", "real_time_factor", "ground_stiffness"}
NON_NEGATIVE = {"max_stamp_age", "future_stamp_tolerance", "command_timeout", "ground_damping", "ground_friction"}


def test_every_parameter_is_described(arm, ros):
    assert set(ros.list_parameters()) == set(TYPES), sorted(set(ros.list_parameters()) ^ set(TYPES))
    names = sorted(TYPES)
    described = ros.describe_parameters(names)
    values = ros.get_parameters(names)
    assert ros.get_parameter_types(names) == {n: TYPES[n].value for n in names}
    for name in names:
        d = described[name]
        assert d.name == name
        assert d.type == TYPES[name].value, (name, d.type)
        assert d.description and "not implemented" not in d.description, (name, d.description)
        assert d.read_only == (name in READ_ONLY), (name, d.read_only)
        if TYPES[name] == T.DOUBLE:
            assert len(d.floating_point_range) == 1 and not d.integer_range, (name, d)
            r = d.floating_point_range[0]
            assert r.from_value <= values[name] <= r.to_value, (name, values[name], r)
            if name in BOUNDED:
                assert (r.from_value, r.to_value) == BOUNDED[name], (name, r)
            elif name in POSITIVE:
                assert 0.0 < r.from_value <= 1e-300 and r.to_value > 1e300, (name, r)
            elif name in NON_NEGATIVE:
                assert r.from_value == 0.0 and r.to_value > 1e300, (name, r)
            else:
                assert r.from_value < -1e300 and r.to_value > 1e300, (name, r)
            assert r.step == 0.0, (name, r)
        elif TYPES[name] == T.INTEGER:
            assert len(d.integer_range) == 1 and not d.floating_point_range, (name, d)
            r = d.integer_range[0]
            assert (r.from_value, r.to_value, r.step) == INTEGER_RANGES[name], (name, r)
        else:
            assert not d.floating_point_range and not d.integer_range, (name, d)
    assert "auto" in described["method"].description and "aba" in described["method"].additional_constraints


def test_read_only_parameter_refuses_a_new_value(arm, ros):
    for name, value in (("mode", "simulate"), ("sim_dt", 0.002), ("passive", ["damping"])):
        before = ros.get_parameters([name])[name]
        result = ros.set_parameter(name, value, TYPES[name])
        assert not result.successful and "read-only" in result.reason, (name, result)
        assert ros.get_parameters([name])[name] == before
    # A writable one next to them still changes (and is put back).
    for value in (True, False):
        result = ros.set_parameter("publish_clock", value, T.BOOL)
        assert result.successful, result.reason


def test_out_of_range_value_is_refused(arm, ros):
    for name, value in (("max_stamp_age", -0.5), ("future_stamp_tolerance", -math.inf)):
        result = ros.set_parameter(name, value, T.DOUBLE)
        assert not result.successful and result.reason, (name, result)
        assert ros.get_parameters([name])[name] == 0.0


def test_unknown_parameters_in_a_params_file_give_one_warning_and_the_node_serves(nodes, ros, tmp_path):
    # Its own name, beside the module's node; the file addresses it by name and by /**.
    name = "unknown_params"
    params = tmp_path / "p.yaml"
    params.write_text(
        "/**:\n  ros__parameters:\n    method: crba\n    nonsense: 1\n"
        f"{name}:\n  ros__parameters:\n    lidar_rate: 10.0\n    gravity: [0.0, 0.0, -1.62]\n"
    )
    log = ros.collector(Log, "/rosout", qos_profile_rosout_default)
    node = nodes.start("-r", f"__node:={name}", "--params-file", params, label=name)
    r = ros.call(DescribeModel, f"/{name}/describe_model", DescribeModel.Request())
    assert r.success and r.method == "crba" and r.gravity.z == -1.62, r
    # The start-up INFO comes after the warning (one writer, in order).
    log.wait(1, sd.EVENT_S, lambda m: m.name == name and "serving robot" in m.msg)
    warnings = log.matching(lambda m: m.name == name and m.level == Log.WARN)
    assert len(warnings) == 1, [w.msg for w in warnings]
    assert "nonsense" in warnings[0].msg and "lidar_rate" in warnings[0].msg and str(params) in warnings[0].msg
    assert node.log().count("ignoring parameters") == 1, node.log()[-2000:]
    assert "nonsense" not in ros.list_parameters(node=f"/{name}")


def test_default_yaml_lists_every_parameter_with_its_default(arm, ros):
    import yaml

    listed = yaml.safe_load((sd.REPO / "config" / "default.yaml").read_text())["spatial_dynamics"]["ros__parameters"]
    assert set(listed) == set(TYPES), sorted(set(listed) ^ set(TYPES))
    running = ros.get_parameters(sorted(TYPES))
    for name, value in listed.items():
        got = running[name]
        got = list(got) if not isinstance(got, (str, bool, int, float)) else got
        assert got == value, (name, value, got)
