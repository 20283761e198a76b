"""`spatial_dynamics replay` against Pinocchio, on bags written by rosbags.

Bags are written with ``rosbags`` (MCAP, with and without zstd chunks, and sqlite3), with and
without effort commands and a ``/robot_description`` topic, and with bad messages mixed in. The
replay's output MCAP is read back with ``rosbags`` (its typestore registered with our
``msg/msg/JointDynamics.msg``) and every message is checked:

* ``/spatial_dynamics/gravity_effort``: ``pin.computeGeneralizedGravity(q)``;
* ``/spatial_dynamics/acceleration``: ``pin.aba(q, v, tau_cmd)`` with the latest command before
  the joint state in log time (zero before the first);
* ``/spatial_dynamics/measured_dynamics``: the accelerations of the documented finite-difference
  scheme, computed here independently (numpy, from the input messages), and
  ``pin.rnea(q, v, a)`` with them; on the smooth test trajectory they also approach the analytic
  accelerations (second order inside segments, first order at segment ends);
* stamps are the inputs' header stamps and log times the inputs' log times; names follow each
  input message's order (joints without a coordinate left out);
* bad messages (truncated, NaN, unknown or missing joint, wrong length) are skipped and counted
  in the ``--json`` summary, by kind.

The scheme (see ``src/joint_states/differences.rs``): samples ``i-1, i`` are one segment when both carry
velocities and ``0 < t_i - t_{i-1} <= max_gap`` (0.1 s; t = header stamp); inside a segment
``a_i = [h-^2 (v+ - v) + h+^2 (v - v-)] / (h- h+ (h- + h+))``, at its ends one-sided differences,
and an isolated sample gets no measured-dynamics message.

The default arm's joint7 is continuous: Pinocchio stores (cos, sin) for it.
"""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

REPO = Path(__file__).resolve().parents[2]
BIN = os.environ.get("SPATIAL_DYNAMICS_BIN") or str(REPO / "target" / "release" / "spatial_dynamics")
URDF = REPO / "config" / "models" / "default_arm.urdf"
JOINTS = [f"joint{k}" for k in range(1, 8)]
MAX_GAP = 0.1
NODE = "/spatial_dynamics"

TS = get_typestore(Stores.ROS2_JAZZY)
TS.register(
    get_types_from_msg(
        (REPO / "msg" / "msg" / "JointDynamics.msg").read_text(), "spatial_dynamics_msgs/msg/JointDynamics"
    )
)
JointState = TS.types["sensor_msgs/msg/JointState"]
Header = TS.types["std_msgs/msg/Header"]
Time = TS.types["builtin_interfaces/msg/Time"]
String = TS.types["std_msgs/msg/String"]
JS = "sensor_msgs/msg/JointState"


class Pin:
    """Pinocchio on a URDF text; our joint names ↔ its q, v."""

    def __init__(self, urdf_text):
        self.model = pin.buildModelFromXML(urdf_text)
        self.data = self.model.createData()
        self.q_of, self.v_of, self.continuous = {}, {}, {}
        for j, name in enumerate(self.model.names):
            if j == 0:
                continue
            joint = self.model.joints[j]
            self.q_of[name], self.v_of[name] = joint.idx_q, joint.idx_v
            self.continuous[name] = joint.nq == 2
        assert set(self.q_of) == set(JOINTS), self.model.names

    def q(self, values):
        q = np.zeros(self.model.nq)
        for name, x in values.items():
            if self.continuous[name]:
                q[self.q_of[name] : self.q_of[name] + 2] = [np.cos(x), np.sin(x)]
            else:
                q[self.q_of[name]] = x
        return q

    def v(self, values):
        v = np.zeros(self.model.nv)
        for name, x in values.items():
            v[self.v_of[name]] = x
        return v

    def named(self, vec, names):
        return np.array([vec[self.v_of[n]] for n in names])


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def state_msg(t_ns, names, position, velocity, frame_id="base"):
    return JointState(
        header=Header(stamp=Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000), frame_id=frame_id),
        name=list(names),
        position=np.asarray(position, dtype=float),
        velocity=np.asarray(velocity, dtype=float),
        effort=np.array([], dtype=float),
    )


def cdr(msg, msgtype=JS):
    return bytes(TS.serialize_cdr(msg, msgtype))


# A smooth motion: q_j(t) = A_j sin(w_j t + p_j), so v and a are known in closed form.
AMP = np.array([0.5, 0.4, 0.6, 0.3, 0.5, 0.4, 1.0])
OMEGA = np.array([2.0, 3.0, 1.5, 2.5, 3.0, 2.0, 1.0])
PHASE = np.array([0.1, 0.7, -0.3, 1.2, 0.0, -1.0, 2.0])


def motion(t):
    s = OMEGA * t + PHASE
    return AMP * np.sin(s), AMP * OMEGA * np.cos(s), -AMP * OMEGA**2 * np.sin(s)


def make_inputs(n=4500, commands=True, seed=7):
    """Joint states (valid and bad) and effort commands, in log-time order.

    Returns (records, expected): records are (topic, msgtype, log_time, bytes); expected lists
    the valid joint states as dicts (log_time, t, names, q, v, has_v, a_true) in order, the
    commands as (log_time, {name: effort}), and the bad-message counts by kind.
    """
    rng = np.random.default_rng(seed)
    orders = [
        ["joint3", "joint1", "joint7", "joint2", "joint6", "joint4", "joint5"],
        JOINTS,
        # A joint without a coordinate (fixed) may be named: it is ignored.
        ["flange_joint"] + JOINTS[::-1],
    ]
    t = 1_700_000_000_000_000_000  # ns, a realistic epoch
    records, states, cmds = [], [], []
    bad = {"unreadable message": 0, "bad position": 0, "bad joint names": 0}
    bad_cmd = 0
    for k in range(n):
        step = 2_000_000 + int(rng.integers(-400_000, 400_000))  # 2 ms ± 0.4 ms
        if k in (700, 2047, 2049):
            step = 250_000_000  # a gap longer than max_gap: a new segment
        if k in (1300, 3001, 3002):
            step = 150_000_000  # around 3001: an isolated sample
        if k == 1800:
            step = 0  # a repeated stamp: a reset
        t += step
        # Received 0.6-0.8 ms later, in order (bad messages and commands fit in between).
        log = max(t + 600_000 + int(rng.integers(0, 200_000)), records[-1][2] + 1_000 if records else 0)
        ts = (t - 1_700_000_000_000_000_000) * 1e-9
        q, v, a = motion(ts)
        names = orders[k % 3 if k % 97 == 0 else 0]
        has_v = k not in (1500, 4200)
        pos = {n: q[JOINTS.index(n)] if n in JOINTS else 0.123 for n in names}
        vel = {n: v[JOINTS.index(n)] if n in JOINTS else 0.0 for n in names}
        msg = state_msg(t, names, [pos[n] for n in names], [vel[n] for n in names] if has_v else [])
        records.append(("/joint_states", JS, log, cdr(msg)))
        states.append(
            dict(log=log, t=t, names=[n for n in names if n in JOINTS], q=q, v=v if has_v else 0 * v, has_v=has_v, a=a)
        )
        if commands and k % 10 == 3:
            tau = {n: float(x) for n, x in zip(JOINTS, rng.normal(0, 5, 7))}
            names_c = list(rng.permutation(JOINTS))
            cmd = state_msg(t, names_c, [], [])
            cmd.effort = np.array([tau[n] for n in names_c])
            records.append((NODE + "/effort_command", JS, log + 50_000, cdr(cmd)))
            cmds.append((log + 50_000, tau))
        if commands and k % 500 == 250:
            # A bad command (one effort short): skipped, the previous command holds.
            cmd = state_msg(t, JOINTS, [], [])
            cmd.effort = np.ones(6)
            records.append((NODE + "/effort_command", JS, log + 60_000, cdr(cmd)))
            bad_cmd += 1
        if k % 300 == 150:
            # Bad joint states between good ones: skipped; the neighbours stay one segment.
            kind = ["unreadable message", "bad position", "bad joint names", "bad joint names", "bad position"][
                (k // 300) % 5
            ]
            blog = log + 100_000
            if kind == "unreadable message":
                data = cdr(msg)[:-5]
            elif kind == "bad position" and (k // 300) % 2:
                bq = [pos[n] for n in names]
                bq[2] = float("nan")
                data = cdr(state_msg(t, names, bq, [vel[n] for n in names]))
            elif kind == "bad position":
                data = cdr(state_msg(t, names, [pos[n] for n in names][:-1], [vel[n] for n in names]))
            elif (k // 300) % 2:
                data = cdr(state_msg(t, names[:-1] + ["joint9"], [pos[n] for n in names], [vel[n] for n in names]))
            else:
                data = cdr(state_msg(t, names[:-1], [pos[n] for n in names[:-1]], [vel[n] for n in names[:-1]]))
            records.append(("/joint_states", JS, blog, data))
            bad[kind] += 1
    return records, dict(states=states, cmds=cmds, bad=bad, bad_cmd=bad_cmd)


def write_bag(path, storage, records, description=None, zstd_chunks=False):
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    writer = Writer(path, version=9, storage_plugin=plugin)
    if zstd_chunks:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        conns = {}

        def conn(topic, msgtype):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=TS)
            return conns[topic]

        if description is not None:
            first = min(r[2] for r in records) - 1_000_000
            writer.write(conn("/robot_description", "std_msgs/msg/String"), first, cdr(String(data=description), "std_msgs/msg/String"))
        for topic, msgtype, log, data in sorted(records, key=lambda r: r[2]):
            writer.write(conn(topic, msgtype), log, data)


def replay(bag, out, *extra):
    run = subprocess.run(
        [BIN, "replay", "--bag", str(bag), "--out", str(out), "--json", *extra],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout), run.stderr


def read_output(path):
    out = {}
    with Reader(path) as reader:
        for conn in reader.connections:
            assert conn.ext.serialization_format == "cdr"
        for conn, log, raw in reader.messages():
            out.setdefault(conn.topic, []).append((log, TS.deserialize_cdr(raw, conn.msgtype), conn.msgtype))
    return out


def expected_accelerations(states):
    """The documented scheme, written here from its description."""
    n = len(states)
    joins = [False] * n
    for i in range(1, n):
        h = states[i]["t"] - states[i - 1]["t"]
        joins[i] = states[i]["has_v"] and states[i - 1]["has_v"] and 0 < h <= MAX_GAP * 1e9
    result = []
    for i, s in enumerate(states):
        prev = joins[i]
        nxt = i + 1 < n and joins[i + 1]
        if not s["has_v"] or not (prev or nxt):
            result.append(None)
            continue
        v = s["v"]
        if prev:
            hm = (s["t"] - states[i - 1]["t"]) * 1e-9
            vm = states[i - 1]["v"]
        if nxt:
            hp = (states[i + 1]["t"] - s["t"]) * 1e-9
            vp = states[i + 1]["v"]
        if prev and nxt:
            a = (hm**2 * (vp - v) + hp**2 * (v - vm)) / (hm * hp * (hm + hp))
            result.append(("central", a))
        elif nxt:
            result.append(("forward", (vp - v) / hp))
        else:
            result.append(("backward", (v - vm) / hm))
    return result


def close(ours, ref, tol):
    ours, ref = np.asarray(ours), np.asarray(ref)
    return np.linalg.norm(ours - ref) <= tol * max(1.0, np.linalg.norm(ref))


def check_replay(tmp_path, storage, commands, description, zstd_chunks=False, extra=(), n=4500):
    records, exp = make_inputs(n=n, commands=commands)
    urdf_text = URDF.read_text()
    if description:
        # A heavier tool than the embedded default: only the bag's description gives these torques.
        urdf_text = urdf_text.replace('<mass value="0.5"/>', '<mass value="2.5"/>', 1)
        assert urdf_text != URDF.read_text()
    bag = tmp_path / "in"
    write_bag(bag, storage, records, description=urdf_text if description else None, zstd_chunks=zstd_chunks)
    out = tmp_path / "out.mcap"
    summary, stderr = replay(bag, out, *extra)
    ref = Pin(urdf_text)

    states, cmds = exp["states"], exp["cmds"]
    js_key = "/joint_states"
    cmd_key = NODE + "/effort_command"
    assert summary["read"][js_key] == len(states) + sum(exp["bad"].values())
    assert summary["read"][cmd_key] == len(cmds) + exp["bad_cmd"]
    skipped = summary["skipped"][js_key]
    assert skipped["total"] == sum(exp["bad"].values()), stderr
    assert {k: v["count"] for k, v in skipped["kinds"].items()} == {k: v for k, v in exp["bad"].items() if v}
    assert summary["skipped"][cmd_key]["total"] == exp["bad_cmd"]

    got = read_output(out)
    gravity = got[NODE + "/gravity_effort"]
    accel = got[NODE + "/acceleration"]
    measured = got.get(NODE + "/measured_dynamics", [])
    assert len(gravity) == len(accel) == len(states)
    assert gravity[0][2] == JS and accel[0][2] == "spatial_dynamics_msgs/msg/JointDynamics"

    # Gravity and forward dynamics under the latest command, message by message.
    ci, tau_cmd = 0, {n: 0.0 for n in JOINTS}
    for s, (glog, g, _), (alog, a, _) in zip(states, gravity, accel):
        while ci < len(cmds) and cmds[ci][0] <= s["log"]:
            tau_cmd = cmds[ci][1]
            ci += 1
        assert glog == alog == s["log"]
        assert stamp_ns(g.header) == stamp_ns(a.header) == s["t"] and g.header.frame_id == "base"
        assert list(g.name) == list(a.name) == s["names"]
        qd = dict(zip(JOINTS, s["q"]))
        vd = dict(zip(JOINTS, s["v"]))
        q, v = ref.q(qd), ref.v(vd)
        assert np.allclose(g.position, [qd[n] for n in s["names"]], rtol=0, atol=0)
        assert close(g.effort, ref.named(pin.computeGeneralizedGravity(ref.model, ref.data, q), s["names"]), 1e-9)
        assert len(g.velocity) == 0
        tau = ref.v(tau_cmd)
        qdd = pin.aba(ref.model, ref.data, q, v, tau)
        assert close(a.acceleration, ref.named(qdd, s["names"]), 1e-9)
        assert np.array_equal(a.effort, [tau_cmd[n] for n in s["names"]])
        assert np.array_equal(a.velocity, [vd[n] for n in s["names"]])

    # Measured dynamics: our finite differences, then RNEA.
    fd = expected_accelerations(states)
    present = [(s, f) for s, f in zip(states, fd) if f is not None]
    assert len(measured) == len(present)
    assert summary["not_estimated"]["total"] == len(states) - len(present)
    kinds = {"central": 0, "forward": 0, "backward": 0}
    for (s, (kind, a_ref)), (mlog, m, _) in zip(present, measured):
        kinds[kind] += 1
        assert mlog == s["log"] and stamp_ns(m.header) == s["t"]
        order = [JOINTS.index(n) for n in s["names"]]
        assert close(m.acceleration, a_ref[order], 1e-9), (kind, m.acceleration, a_ref[order])
        # Against the analytic acceleration: second order inside, first order at the ends.
        assert close(m.acceleration, s["a"][order], 1e-3 if kind == "central" else 5e-2), kind
        q, v = ref.q(dict(zip(JOINTS, s["q"]))), ref.v(dict(zip(JOINTS, s["v"])))
        tau = pin.rnea(ref.model, ref.data, q, v, ref.v(dict(zip(JOINTS, a_ref))))
        assert close(m.effort, ref.named(tau, s["names"]), 1e-9)
    assert min(kinds.values()) >= 2, kinds  # every branch of the scheme was exercised
    return summary, out


@pytest.mark.parametrize(
    "storage,commands,description,zstd_chunks",
    [
        ("mcap", True, True, False),
        ("mcap", False, False, True),
        ("sqlite3", True, False, False),
        ("sqlite3", False, True, False),
    ],
    ids=["mcap-commands-description", "mcap-zstd-chunks", "sqlite3-commands", "sqlite3-description"],
)
def test_replay_matches_pinocchio(tmp_path, storage, commands, description, zstd_chunks):
    extra = () if description else ("--urdf", str(URDF)) if storage == "sqlite3" else ("--builtin", "default_arm")
    summary, _ = check_replay(tmp_path, storage, commands, description, zstd_chunks, extra=extra)
    assert ("bag's /robot_description" in summary["model"]["source"]) == description


def test_output_is_a_ros2_mcap_and_independent_of_jobs(tmp_path):
    records, _ = make_inputs(n=2600, commands=True, seed=3)
    bag = tmp_path / "in.mcap.d"
    write_bag(bag, "mcap", records)
    outs = []
    for jobs in ("1", "3"):
        out = tmp_path / f"out{jobs}.mcap"
        replay(bag / "in.mcap.d.mcap", out, "--jobs", jobs, "--compression", "lz4")
        outs.append(read_output(out))
    assert outs[0].keys() == outs[1].keys()
    for topic in outs[0]:
        a = [(log, TS.serialize_cdr(m, t).tobytes()) for log, m, t in outs[0][topic]]
        b = [(log, TS.serialize_cdr(m, t).tobytes()) for log, m, t in outs[1][topic]]
        assert a == b, topic
    # The MCAP header's profile, and the schemas: ros2msg with every dependency.
    data = (tmp_path / "out1.mcap").read_bytes()
    assert data[:8] == b"\x89MCAP0\r\n" and data[8] == 0x01
    profile_len = int.from_bytes(data[17:21], "little")
    assert data[21 : 21 + profile_len] == b"ros2"
    with Reader(tmp_path / "out1.mcap") as reader:
        for conn in reader.connections:
            assert conn.msgdef.format.name == "MSG"
            assert "MSG: std_msgs/Header" in conn.msgdef.data and "MSG: builtin_interfaces/Time" in conn.msgdef.data


def test_bad_invocations_fail_with_a_message(tmp_path):
    records, _ = make_inputs(n=20, commands=False)
    bag = tmp_path / "bag"
    write_bag(bag, "sqlite3", records)
    out = tmp_path / "o.mcap"
    cases = [
        (["--joint-states", "/nope"], "no topic /nope"),
        (["--floating-base"], "floating base"),
        (["--max-gap", "0"], "--max-gap"),
        (["--zstd-level", "0"], "not a zstd level"),
    ]
    for extra, message in cases:
        run = subprocess.run(
            [BIN, "replay", "--bag", str(bag), "--out", str(out), *extra], capture_output=True, text=True, timeout=60
        )
        assert run.returncode != 0 and message in run.stderr, (extra, run.stderr)
    run = subprocess.run(
        [BIN, "replay", "--bag", str(tmp_path / "missing"), "--out", str(out)], capture_output=True, text=True, timeout=60
    )
    assert run.returncode != 0 and "missing" in run.stderr


@pytest.mark.parametrize("method", ["crba", "rnea_columns"])
def test_other_methods_match_pinocchio(tmp_path, method):
    # Forward dynamics by another method is still pin.aba's result (to 1e-9); rosbag2's zstd level.
    extra = ("--builtin", "default_arm", "--method", method, "--zstd-level", "1")
    check_replay(tmp_path, "mcap", True, False, extra=extra, n=1400)


def test_overflowing_state_is_counted_not_fatal(tmp_path):
    """A joint state whose dynamics overflow (velocities of 1e200) loses its outputs, counted;
    the others keep theirs."""
    records, exp = make_inputs(n=300, commands=True)
    target = exp["states"][100]
    k = next(i for i, r in enumerate(records) if r[0] == "/joint_states" and r[2] == target["log"])
    msg = TS.deserialize_cdr(records[k][3], JS)
    msg.velocity = np.full(len(msg.name), 1e200)
    records[k] = records[k][:3] + (cdr(msg),)
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    summary, stderr = replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm")
    kinds = summary["skipped"]["/joint_states"]["kinds"]
    assert kinds["dynamics failed"]["count"] == 1, stderr
    assert "acceleration" in kinds["dynamics failed"]["first"], kinds
    assert summary["not_estimated"]["kinds"]["inverse dynamics failed"]["count"] >= 1, stderr
    written = summary["written"]
    assert written[NODE + "/gravity_effort"] == written[NODE + "/acceleration"] == len(exp["states"]) - 1


def run_replay(bag, out, *extra):
    return subprocess.run(
        [BIN, "replay", "--bag", str(bag), "--out", str(out), "--json", *extra], capture_output=True, text=True, timeout=60
    )


def test_no_answered_joint_state_fails_and_keeps_the_earlier_output(tmp_path):
    """Every joint state names a joint the model lacks: the run fails, says why with counts
    (the names that did not match first), leaves the earlier output as it was and no partial
    file beside it."""
    records = []
    t = 1_700_000_000_000_000_000
    for k in range(30):
        names = JOINTS[:-1] + ["wrist9"] if k % 3 else JOINTS
        position = np.zeros(7) if k % 3 else np.array([0.0] * 6 + [float("nan")])
        records.append(("/joint_states", JS, t + k * 2_000_000, cdr(state_msg(t + k * 2_000_000, names, position, np.zeros(7)))))
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    out = tmp_path / "out.mcap"
    out.write_bytes(b"earlier output")
    run = run_replay(bag / "in.mcap", out, "--builtin", "default_arm")
    assert run.returncode != 0, run.stderr
    assert "no joint state was answered" in run.stderr, run.stderr
    lines = run.stderr[run.stderr.index("no joint state was answered") :].splitlines()
    assert "20" in lines[1] and "bad joint names" in lines[1] and "wrist9" in lines[1], lines
    assert "10" in lines[2] and "bad position" in lines[2], lines
    assert out.read_bytes() == b"earlier output"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "out.mcap"]


def test_a_failed_read_leaves_no_partial_output(tmp_path):
    records, _ = make_inputs(n=50, commands=False)
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    mcap = bag / "in.mcap"
    data = mcap.read_bytes()
    # The joint states' channel recorded with another type: an error when it is read.
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(data.replace(b"sensor_msgs/msg/JointState", b"sensor_msgs/msg/JointStatf"))
    out = tmp_path / "out.mcap"
    run = run_replay(bad, out, "--builtin", "default_arm", "--joint-states", "/joint_states")
    assert run.returncode != 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.mcap", "in"], run.stderr


@pytest.mark.parametrize("given", ["joint_states", "/joint_states"])
def test_topics_match_as_recorded_with_or_without_a_leading_slash(tmp_path, given):
    """rosbags and some recorders store names without the leading slash."""
    records, exp = make_inputs(n=40, commands=False)
    records = [("joint_states",) + r[1:] for r in records]
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    run = run_replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm", "--joint-states", given)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["written"][NODE + "/gravity_effort"] == len(exp["states"])


def test_rates_are_never_computed_from_a_zero_duration(tmp_path):
    records, _ = make_inputs(n=3, commands=False)
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    run = run_replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm", "--jobs", "1")
    assert run.returncode == 0, run.stderr
    s = json.loads(run.stdout)
    cpu, rate = s["cpu_seconds"], s["joint_states_per_cpu_second"]
    assert (cpu is None or cpu == 0) == (rate is None), s
    if rate is not None:
        assert rate == pytest.approx(s["read"]["/joint_states"] / cpu)
    assert (s["joint_states_per_second"] is None) == (s["seconds"] == 0)


def test_an_output_that_would_replace_the_input_is_refused(tmp_path):
    """The output may not be the bag's own file (given directly or through its directory), a
    file inside the bag directory that a later read would take for a storage file, or a
    directory; the input stays as it was."""
    records, _ = make_inputs(n=20, commands=False)
    bag = tmp_path / "bag"
    write_bag(bag, "mcap", records)
    storage = bag / "bag.mcap"
    before = storage.read_bytes()
    cases = [
        (storage, storage, "would replace the input"),
        (bag, storage, "would replace the input"),
        (bag, bag / "metadata.yaml", "would replace the input"),
        (bag, bag / "out.mcap", "inside the bag directory"),
        (bag, tmp_path, "is a directory"),
    ]
    for given, out, message in cases:
        run = run_replay(given, out, "--builtin", "default_arm")
        assert run.returncode != 0 and message in run.stderr, (given, out, run.stderr)
    assert storage.read_bytes() == before
    assert sorted(p.name for p in bag.iterdir()) == ["bag.mcap", "metadata.yaml"]
    run = run_replay(bag, tmp_path / "o.mcap", "--builtin", "default_arm", "--jobs", "100000")
    assert run.returncode != 0 and "--jobs must be at most" in run.stderr, run.stderr


def test_an_interrupted_run_leaves_no_partial_output(tmp_path):
    """SIGINT or SIGTERM mid-run: the run stops, says so, removes its partial output and keeps
    the earlier one. (A 200-link pendulum makes each joint state slow enough that the run is
    still going when the signal comes.)"""
    import signal
    import time

    joints = [f"joint{k}" for k in range(1, 201)]
    t0 = 1_700_000_000_000_000_000
    records = [
        ("/joint_states", JS, t0 + k * 1_000_000, cdr(state_msg(t0 + k * 1_000_000, joints, np.full(200, 0.1), np.zeros(200))))
        for k in range(60_000)
    ]
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    for sig in (signal.SIGINT, signal.SIGTERM):
        out_dir = tmp_path / f"out_{sig.name}"
        out_dir.mkdir()
        out = out_dir / "out.mcap"
        out.write_bytes(b"earlier output")
        proc = subprocess.Popen(
            [BIN, "replay", "--bag", str(bag), "--out", str(out), "--builtin", "pendulum:200", "--jobs", "1"],
            stderr=subprocess.PIPE,
            text=True,
        )
        deadline = time.monotonic() + 30
        while not any(p.name.endswith(".partial") for p in out_dir.iterdir()):
            assert proc.poll() is None and time.monotonic() < deadline, "the run ended before it was interrupted"
            time.sleep(0.01)
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=60)
        assert proc.returncode == 1 and "interrupted by a signal" in stderr, (sig, proc.returncode, stderr)
        assert sorted(p.name for p in out_dir.iterdir()) == ["out.mcap"], stderr
        assert out.read_bytes() == b"earlier output"
