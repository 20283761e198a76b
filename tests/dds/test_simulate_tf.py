"""Simulate mode with a floating base publishes world → base link on /tf (tf2_msgs/TFMessage)
with each joint state; `publish_tf: false` publishes none.

tf2_msgs has no wheel on PyPI: launch_scripts/setup_python_env.sh builds it from
tests/dds/interfaces/tf2_msgs (the upstream TFMessage) into the venv.

Reference: a free box released at rest at the world origin falls as z = −g t²/2 (closed form)
without turning, t the stamp's simulated time. RK4 integrates a constant acceleration exactly,
so the only error is the stamp's resolution: t is rounded to 1 ns, which moves z by up to
g t · 1 ns; the tolerance is that plus 1e-9 m of rounding.
"""

from nav_msgs.msg import Odometry
from tf2_msgs.msg import TFMessage

import sd_dds_support as sd

NODE = "/spatial_dynamics"
G = 9.81
BOX_URDF = """<robot name="box">
  <link name="box">
    <inertial>
      <mass value="2.0"/>
      <inertia ixx="0.0019" iyy="0.0069" izz="0.0083" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
</robot>"""


def start(nodes, tmp_path, label, publish_tf):
    params = tmp_path / f"{label}.yaml"
    params.write_text(
        "spatial_dynamics:\n  ros__parameters:\n"
        f"    robot_description: {sd.yaml_string(BOX_URDF)}\n"
        "    floating_base: true\n    mode: simulate\n    integrator: rk4\n"
        f"    sim_dt: 0.001\n    publish_rate: 50.0\n    publish_tf: {str(publish_tf).lower()}\n"
    )
    return nodes.start("--params-file", str(params), label=label)


def seconds(stamp):
    return stamp.sec + 1e-9 * stamp.nanosec


def test_tf_carries_the_pose_of_a_falling_box(nodes, ros, tmp_path):
    tf = ros.collector(TFMessage, "/tf", sd.qos_reliable())
    start(nodes, tmp_path, "tf", publish_tf=True)
    tf.wait_publisher()
    # Twenty transforms past 0.1 s of simulated time (the box has fallen ≥ 5 cm by then).
    messages = tf.wait(n=20, timeout=sd.EVENT_S, predicate=lambda m: seconds(m.transforms[0].header.stamp) > 0.1)
    for message in messages:
        assert len(message.transforms) == 1, message
        tr = message.transforms[0]
        assert tr.header.frame_id == "world" and tr.child_frame_id == "box", tr
        t = seconds(tr.header.stamp)
        p, r = tr.transform.translation, tr.transform.rotation
        tolerance = G * t * 1e-9 + 1e-9
        assert abs(p.z - (-0.5 * G * t * t)) <= tolerance, (t, p.z, -0.5 * G * t * t)
        assert abs(p.x) <= 1e-12 and abs(p.y) <= 1e-12, p
        assert max(abs(r.x), abs(r.y), abs(r.z), abs(r.w - 1.0)) <= 1e-12, r


def test_publish_tf_false_publishes_no_transform(nodes, ros, tmp_path):
    tf = ros.collector(TFMessage, "/tf", sd.qos_reliable())
    states = ros.collector(Odometry, f"{NODE}/base_state", sd.qos_reliable())
    start(nodes, tmp_path, "no_tf", publish_tf=False)
    # Matched to the node's /tf publisher, then half a simulated second of base states: had the
    # node sent a transform with any of them, it would have arrived.
    tf.wait_publisher()
    states.wait_publisher()
    states.wait(n=25, timeout=sd.EVENT_S)
    ros.spin_for(0.5)
    assert tf.messages == [], tf.messages[:1]
