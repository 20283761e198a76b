"""Helpers for the DDS tests: the node as a subprocess, an rclpy session (service calls,
topic collectors, parameter services), and Pinocchio references mapped by joint name.

Nothing here computes dynamics of its own: every expected value comes from Pinocchio (``pin``)
on the same URDF, or from closed forms written in the test files.
"""

from __future__ import annotations

import glob
import json
import math
import os
import shutil
import signal
import site
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

REPO = Path(__file__).resolve().parents[2]
MODELS = REPO / "config" / "models"
DEFAULT_ARM_URDF = MODELS / "default_arm.urdf"
PARTICLE_URDF = MODELS / "particle.urdf"
MIMIC_GRIPPER_URDF = MODELS / "mimic_gripper.urdf"
LAMP_URDF = MODELS / "lamp.urdf"
ARM_JOINTS = [f"joint{i}" for i in range(1, 8)]
NODE = "/spatial_dynamics"
REL_TOL = 1e-9
# Upper bound of every wait for an event (a message, a report, a service, a node): waits end as
# soon as the event happens, so the bound only matters when it never does. Generous, so that a
# busy machine (CI shares 2 cores) delays a test instead of failing it.
EVENT_S = 60.0

# --------------------------------------------------------------------------------------------
# Locating things
# --------------------------------------------------------------------------------------------


def binary_path() -> Path:
    env = os.environ.get("SPATIAL_DYNAMICS_BIN")
    return Path(env) if env else REPO / "target" / "release" / "spatial_dynamics"


def ros_versions() -> str:
    """rclpy's, the RMW's and Fast DDS's versions, as installed (for the test report's header)."""
    from importlib import metadata

    def version(*dists):
        for dist in dists:
            try:
                return metadata.version(dist)
            except metadata.PackageNotFoundError:
                pass
        return "unknown"

    rmw = rclpy.get_rmw_implementation_identifier()
    # The Fast DDS wheel is `ros-fastdds` from Fast DDS 3 on, `ros-fastrtps` before.
    return (
        f"rclpy {version('ros-rclpy')}, {rmw} {version('ros-' + rmw.replace('_', '-'))}, "
        f"Fast DDS {version('ros-fastdds', 'ros-fastrtps')}"
    )


def robots_dir() -> Path:
    """example-robot-data's robots/ directory (the PyPI wheel ships it under cmeel.prefix)."""
    candidates = []
    if os.environ.get("EXAMPLE_ROBOT_DATA_DIR"):
        candidates.append(Path(os.environ["EXAMPLE_ROBOT_DATA_DIR"]))
    for root in (sys.prefix, sys.base_prefix, *site.getsitepackages()):
        for pattern in (
            "lib/python*/site-packages/cmeel.prefix/share/example-robot-data/robots",
            "cmeel.prefix/share/example-robot-data/robots",
            "share/example-robot-data/robots",
        ):
            candidates.extend(Path(p) for p in sorted(glob.glob(os.path.join(root, pattern))))
    for cand in candidates:
        if (cand / "solo_description").is_dir():
            return cand
    raise FileNotFoundError("example-robot-data robots/ not found (pip install example-robot-data)")


def solo12_urdf() -> Path:
    return robots_dir() / "solo_description" / "robots" / "solo12.urdf"


def anymal_urdf() -> Path:
    for rel in ("anymal_b_simple_description/robots/anymal.urdf", "anymal_description/robots/anymal.urdf"):
        if (robots_dir() / rel).is_file():
            return robots_dir() / rel
    raise FileNotFoundError("ANYmal URDF not found in example-robot-data")


# --------------------------------------------------------------------------------------------
# The node as a subprocess
# --------------------------------------------------------------------------------------------

LIVE_NODES: list = []  # every NodeProcess started and not yet stopped (for failure reports)

# A node gets SIGTERM when the test process that started it dies (killed, timed out), instead of
# living on in its own session: util-linux's setpriv sets the parent-death signal and execs it.
# The kernel sends it when the *thread* that started the process ends: start nodes (and any
# other process given this prefix) from the main thread, as the fixtures do, never from a
# short-lived worker thread.
DIE_WITH_TESTS = ["setpriv", "--pdeathsig", "TERM"] if shutil.which("setpriv") else []


class NodeProcess:
    """`spatial_dynamics node ARGS` (or `BINARY ARGS` with ``subcommand=()``, for the
    `spatial_dynamics_node` executable), output to a log file; stopped by SIGINT, then SIGKILL."""

    def __init__(self, binary: Path, args, env: dict, log_path: Path, label: str, expect_exit=False,
                 subcommand=("node",)):
        self.args = [str(binary), *subcommand, *[str(a) for a in args]]
        self.label = label
        self.log_path = log_path
        self.expect_exit = expect_exit
        self._log = open(log_path, "wb")
        self.proc = subprocess.Popen(
            [*DIE_WITH_TESTS, *self.args],
            stdout=self._log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=env,
            start_new_session=True,
        )
        LIVE_NODES.append(self)

    def poll(self):
        return self.proc.poll()

    def log(self) -> str:
        self._log.flush()
        try:
            return self.log_path.read_text(errors="replace")
        except OSError as exc:
            return f"(log unreadable: {exc})"

    def describe(self) -> str:
        rc = self.proc.poll()
        state = "running" if rc is None else f"exited with {rc}"
        return f"node {self.label} ({state}): {' '.join(self.args)}\n--- log {self.log_path} ---\n{self.log()}"

    def assert_alive(self):
        if self.proc.poll() is not None:
            raise AssertionError(f"the node died:\n{self.describe()}")

    def wait_exit(self, timeout=10.0) -> int:
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"the node did not exit within {timeout} s:\n{self.describe()}")

    def stop(self):
        if self.proc.poll() is None:
            try:
                self.proc.send_signal(signal.SIGINT)
                self.proc.wait(3.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5.0)
        self._log.close()
        if self in LIVE_NODES:
            LIVE_NODES.remove(self)


# --------------------------------------------------------------------------------------------
# rclpy session
# --------------------------------------------------------------------------------------------


def qos_reliable(depth=100, latched=False) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def qos_best_effort(depth=100) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.VOLATILE,
    )


QOS_LATCHED = qos_reliable(depth=1, latched=True)


class Collector:
    """Every message received on one topic, in arrival order."""

    def __init__(self, session, msg_type, topic, qos):
        self.session = session
        self.topic = topic
        self.messages = []
        self.sub = session.node.create_subscription(msg_type, topic, self.messages.append, qos)

    def clear(self):
        self.messages.clear()

    def matching(self, predicate=None):
        return [m for m in self.messages if predicate is None or predicate(m)]

    def wait(self, n=1, timeout=EVENT_S, predicate=None):
        """Waits until `n` messages (satisfying `predicate`) have arrived; returns them."""
        ok = self.session.spin_until(lambda: len(self.matching(predicate)) >= n, timeout)
        got = self.matching(predicate)
        if not ok:
            raise AssertionError(
                f"{self.topic}: {len(got)} of {n} expected message(s) within {timeout} s "
                f"(received {len(self.messages)} in all; last: {self.messages[-1] if self.messages else None})"
            )
        return got[:n] if n else got

    def wait_publisher(self, timeout=EVENT_S):
        if not self.session.spin_until(lambda: self.sub.get_publisher_count() > 0, timeout):
            raise AssertionError(f"no publisher on {self.topic} within {timeout} s")


class RosSession:
    """One rclpy context, node and executor (one per test module)."""

    def __init__(self, domain_id: int, name: str):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._clients = {}
        self._publishers = {}

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)

    # -- spinning ---------------------------------------------------------------------------

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.02, max(0.0, end - time.monotonic())))

    def spin_until(self, predicate, timeout):
        end = time.monotonic() + timeout
        while True:
            if predicate():
                return True
            if time.monotonic() >= end:
                return False
            self.executor.spin_once(timeout_sec=0.02)

    # -- services ---------------------------------------------------------------------------

    def client(self, srv_type, name):
        key = (srv_type, name)
        if key not in self._clients:
            self._clients[key] = self.node.create_client(srv_type, name)
        return self._clients[key]

    def rosout_writers(self):
        """Endpoint GIDs of every /rosout publisher seen (one per node, ghosts of stopped nodes
        included until their lease runs out)."""
        return {bytes(i.endpoint_gid) for i in self.node.get_publishers_info_by_topic("/rosout")}

    def wait_new_node(self, before, timeout=EVENT_S):
        """Waits until a node not in `before` (rosout_writers()) has been discovered."""
        return self.spin_until(lambda: bool(self.rosout_writers() - before), timeout)

    def wait_for_service(self, srv_type, name, timeout=EVENT_S):
        client = self.client(srv_type, name)
        if not self.spin_until(client.service_is_ready, timeout):
            raise AssertionError(f"service {name} not available within {timeout} s")
        return client

    def call(self, srv_type, name, request, timeout=10.0):
        """Calls a service once it is available and returns the response."""
        client = self.wait_for_service(srv_type, name)
        future = client.call_async(request)
        if not self.spin_until(future.done, timeout):
            client.remove_pending_request(future)
            raise AssertionError(f"no answer from {name} within {timeout} s")
        return future.result()

    # -- topics -----------------------------------------------------------------------------

    def collector(self, msg_type, topic, qos=None):
        return Collector(self, msg_type, topic, qos or qos_reliable())

    def publisher(self, msg_type, topic, qos=None, wait=True, timeout=EVENT_S):
        qos = qos or qos_reliable(depth=10)
        key = (msg_type, topic, qos.reliability, qos.durability)
        pub = self._publishers.get(key)
        if pub is None:
            pub = self.node.create_publisher(msg_type, topic, qos)
            self._publishers[key] = pub
        if wait and not self.spin_until(lambda: pub.get_subscription_count() > 0, timeout):
            raise AssertionError(f"no subscriber on {topic} within {timeout} s")
        return pub

    def destroy_publisher(self, pub):
        for key, value in list(self._publishers.items()):
            if value is pub:
                del self._publishers[key]
        self.node.destroy_publisher(pub)

    def exchange(self, publish, collector, predicate, timeout=EVENT_S, period=0.25):
        """Publishes (by calling `publish()`) every `period` s until a message satisfying
        `predicate` arrives on `collector`; returns it. For inputs whose first samples may be lost
        while discovery settles (best-effort topics, freshly matched readers)."""
        end = time.monotonic() + timeout
        while True:
            publish()
            stop = min(end, time.monotonic() + period)
            if self.spin_until(lambda: collector.matching(predicate), max(0.0, stop - time.monotonic())):
                return collector.matching(predicate)[0]
            if time.monotonic() >= end:
                raise AssertionError(
                    f"{collector.topic}: no matching answer within {timeout} s "
                    f"(received {len(collector.messages)}; last: {collector.messages[-1] if collector.messages else None})"
                )

    # -- parameters -------------------------------------------------------------------------

    def list_parameters(self, node=NODE):
        from rcl_interfaces.srv import ListParameters

        return list(self.call(ListParameters, f"{node}/list_parameters", ListParameters.Request()).result.names)

    def get_parameters(self, names, node=NODE):
        """{name: python value} (None for a parameter that is not set)."""
        from rcl_interfaces.srv import GetParameters

        resp = self.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=list(names)))
        assert len(resp.values) == len(names), f"get_parameters{names}: {resp}"
        return {n: parameter_value_to_python(v) for n, v in zip(names, resp.values)}

    def get_parameter_types(self, names, node=NODE):
        from rcl_interfaces.srv import GetParameterTypes

        resp = self.call(GetParameterTypes, f"{node}/get_parameter_types", GetParameterTypes.Request(names=list(names)))
        return dict(zip(names, resp.types))

    def describe_parameters(self, names, node=NODE):
        from rcl_interfaces.srv import DescribeParameters

        resp = self.call(DescribeParameters, f"{node}/describe_parameters", DescribeParameters.Request(names=list(names)))
        return {d.name: d for d in resp.descriptors}

    def set_parameters(self, params, node=NODE):
        """params: list of rclpy Parameter (or (name, value) / (name, type, value) tuples);
        returns the SetParametersResult list."""
        from rcl_interfaces.srv import SetParameters

        msgs = []
        for p in params:
            if isinstance(p, tuple):
                p = Parameter(p[0], value=p[1]) if len(p) == 2 else Parameter(p[0], p[1], p[2])
            msgs.append(p.to_parameter_msg())
        resp = self.call(SetParameters, f"{node}/set_parameters", SetParameters.Request(parameters=msgs))
        assert len(resp.results) == len(msgs), resp
        return list(resp.results)

    def set_parameter(self, name, value, type_=None, node=NODE):
        p = Parameter(name, type_, value) if type_ is not None else Parameter(name, value=value)
        return self.set_parameters([p], node)[0]


# --------------------------------------------------------------------------------------------
# Diagnostics
# --------------------------------------------------------------------------------------------


def status_values(array_msg, status_name):
    """{key: value} of the status named `status_name` in a DiagnosticArray, or None."""
    for status in array_msg.status:
        if status.name == status_name:
            return {kv.key: kv.value for kv in status.values}
    return None


def level(status) -> int:
    """DiagnosticStatus.level (a `byte`: rclpy gives bytes) as an int."""
    lv = status.level
    return lv[0] if isinstance(lv, (bytes, bytearray)) else int(lv)


def dropped_count(values, topic, kind=None):
    """Sum of the "<topic> dropped: <kind>" counters (every kind if `kind` is None)."""
    total = 0
    for key, value in (values or {}).items():
        prefix = f"{topic} dropped: "
        if key.startswith(prefix) and (kind is None or key[len(prefix):] == kind):
            total += int(value)
    return total


# --------------------------------------------------------------------------------------------
# Numbers
# --------------------------------------------------------------------------------------------


def assert_close(got, want, what="", tol=REL_TOL):
    got = np.asarray(got, dtype=float)
    want = np.asarray(want, dtype=float)
    assert got.shape == want.shape, f"{what}: shape {got.shape}, expected {want.shape}"
    err = float(np.linalg.norm(got - want))
    bound = tol * max(1.0, float(np.linalg.norm(want)))
    assert err <= bound, f"{what}: ||got - want|| = {err:.3e} > {bound:.3e}\n got  {got!r}\n want {want!r}"


def stamp_eq(a, b):
    return a.sec == b.sec and a.nanosec == b.nanosec


_stamp_counter = [1000]


def fresh_stamp():
    """A Time that no other message of this process has used."""
    from builtin_interfaces.msg import Time

    _stamp_counter[0] += 1
    return Time(sec=_stamp_counter[0], nanosec=(_stamp_counter[0] * 7919) % 1_000_000_000)


# --------------------------------------------------------------------------------------------
# Pinocchio reference, mapped by joint name
# --------------------------------------------------------------------------------------------


@dataclass
class PinJoint:
    name: str
    kind: str  # revolute | continuous | prismatic | floating
    jid: int
    idx_q: int
    nq: int
    idx_v: int
    nv: int


def _kind(jmodel) -> str:
    short = jmodel.shortname()
    if "FreeFlyer" in short:
        return "floating"
    if (jmodel.nq, jmodel.nv) == (2, 1):
        return "continuous"
    if "Prismatic" in short or short.startswith("JointModelP"):
        return "prismatic"
    return "revolute"


class PinRef:
    """Pinocchio's model of a URDF; states are given by joint NAME as our messages give them.

    Our q of a continuous joint is the angle t, Pinocchio's is (cos t, sin t). The floating base
    (Pinocchio's JointModelFreeFlyer) has q = [x y z qx qy qz qw], v = [linear; angular] in the
    base frame, exactly our base_pose / base_twist fields.
    """

    def __init__(self, urdf_path=None, urdf_text=None, floating=False, gravity=None, locked=None, mimic=False):
        args = [pin.JointModelFreeFlyer()] if floating else []
        kwargs = {"mimic": True} if mimic else {}  # Pinocchio ignores <mimic> unless asked
        if urdf_text is not None:
            model = pin.buildModelFromXML(urdf_text, *args, **kwargs)
        else:
            model = pin.buildModelFromUrdf(str(urdf_path), *args, **kwargs)
        if locked:
            q_lock = pin.neutral(model)
            ids = []
            for name, value in locked.items():
                jid = model.getJointId(name)
                jm = model.joints[jid]
                if jm.nq == 2:
                    q_lock[jm.idx_q : jm.idx_q + 2] = [math.cos(value), math.sin(value)]
                else:
                    q_lock[jm.idx_q] = value
                ids.append(jid)
            model = pin.buildReducedModel(model, ids, q_lock)
        if gravity is not None:
            model.gravity.linear = np.asarray(gravity, dtype=float)
        self.model = model
        self.data = model.createData()
        self.joints = {}
        self.base = None
        for j in range(1, model.njoints):
            jm = model.joints[j]
            if jm.nv == 0:  # a mimic joint (mimic=True): no coordinate of its own
                continue
            pj = PinJoint(model.names[j], _kind(jm), j, jm.idx_q, jm.nq, jm.idx_v, jm.nv)
            if pj.kind == "floating":
                self.base = pj
            else:
                self.joints[pj.name] = pj

    @property
    def names(self):
        """Joint names in Pinocchio's coordinate order (without the floating base)."""
        return [j.name for j in sorted(self.joints.values(), key=lambda j: j.idx_v)]

    # -- building states --------------------------------------------------------------------

    def q(self, names, positions, base_pose=None):
        q = pin.neutral(self.model)
        assert len(names) == len(positions)
        for name, x in zip(names, positions):
            j = self.joints[name]
            if j.kind == "continuous":
                q[j.idx_q : j.idx_q + 2] = [math.cos(x), math.sin(x)]
            else:
                q[j.idx_q] = x
        if self.base is not None:
            pose = base_pose if base_pose is not None else [0, 0, 0, 0, 0, 0, 1]
            q[self.base.idx_q : self.base.idx_q + 7] = pose
        return q

    def v(self, names, values, base6=None):
        v = np.zeros(self.model.nv)
        if values is not None and len(values):
            for name, x in zip(names, values):
                v[self.joints[name].idx_v] = x
        if self.base is not None and base6 is not None:
            v[self.base.idx_v : self.base.idx_v + 6] = base6
        return v

    def pick(self, vec, names):
        """The entries of a v-sized vector for `names`, in that order."""
        return np.array([vec[self.joints[n].idx_v] for n in names])

    def pick_base(self, vec):
        return np.asarray(vec[self.base.idx_v : self.base.idx_v + 6])

    def matrix(self, m, names):
        """Rows/columns of M: the base's 6 (if any), then `names`."""
        idx = []
        if self.base is not None:
            idx.extend(range(self.base.idx_v, self.base.idx_v + 6))
        idx.extend(self.joints[n].idx_v for n in names)
        return np.asarray(m)[np.ix_(idx, idx)]

    # -- algorithms -------------------------------------------------------------------------

    def rnea(self, q, v, a, fext=None):
        if fext is None:
            return pin.rnea(self.model, self.data, q, v, a).copy()
        return pin.rnea(self.model, self.data, q, v, a, fext).copy()

    def aba(self, q, v, tau, fext=None):
        if fext is None:
            return pin.aba(self.model, self.data, q, v, tau).copy()
        return pin.aba(self.model, self.data, q, v, tau, fext).copy()

    def crba(self, q):
        m = np.array(pin.crba(self.model, self.data, q))
        return np.triu(m) + np.triu(m, 1).T

    def gravity(self, q):
        return pin.computeGeneralizedGravity(self.model, self.data, q).copy()

    def fext(self, q, wrenches):
        """Pinocchio's fext (forces in the LOCAL frame of each joint) for link wrenches
        [(link, frame, force[3], torque[3])], each about the link frame's origin, in the link's
        axes (frame "" or the link's name) or world-aligned axes (frame "world")."""
        fext = pin.StdVec_Force()
        for _ in range(self.model.njoints):
            fext.append(pin.Force.Zero())
        pin.framesForwardKinematics(self.model, self.data, q)
        for link, frame, force, torque in wrenches:
            fid = self.model.getFrameId(link, pin.FrameType.BODY)
            assert fid < len(self.model.frames), f"no body frame {link!r} in Pinocchio's model"
            f = self.model.frames[fid]
            force, torque = np.asarray(force, float), np.asarray(torque, float)
            if frame == "world":
                rot = self.data.oMf[fid].rotation  # link axes -> world axes
                force, torque = rot.T @ force, rot.T @ torque
            else:
                assert frame in ("", link)
            local = f.placement.act(pin.Force(force, torque))  # link frame -> joint frame
            fext[f.parentJoint] = fext[f.parentJoint] + local
        return fext


def random_positions(names, rng, urdf_path=None):
    """Random joint positions within URDF limits (continuous: [-pi, pi])."""
    limits = urdf_joint_limits(urdf_path) if urdf_path else {}
    out = []
    for n in names:
        lo, hi = limits.get(n, (-math.pi, math.pi))[:2]
        if not (math.isfinite(lo) and math.isfinite(hi)):
            lo, hi = -math.pi, math.pi
        out.append(float(rng.uniform(lo, hi)))
    return out


# --------------------------------------------------------------------------------------------
# URDF facts (read directly from the XML)
# --------------------------------------------------------------------------------------------


def urdf_joints(path):
    """[(name, type, lower, upper, velocity, effort)] of the URDF's non-fixed joints, in document
    order; missing limits as -inf/+inf (position) and +inf (velocity, effort)."""
    out = []
    for joint in ET.parse(path).getroot().iter("joint"):
        kind = joint.get("type")
        if kind == "fixed":
            continue
        lim = joint.find("limit")
        get = lambda k, d: float(lim.get(k)) if lim is not None and lim.get(k) is not None else d
        if kind == "continuous":
            lo, hi = -math.inf, math.inf
        else:
            lo, hi = get("lower", -math.inf), get("upper", math.inf)
        out.append((joint.get("name"), kind, lo, hi, get("velocity", math.inf), get("effort", math.inf)))
    return out


def urdf_joint_limits(path):
    return {n: (lo, hi) for n, _, lo, hi, _, _ in urdf_joints(path)}


def urdf_links(path):
    return [link.get("name") for link in ET.parse(path).getroot().iter("link")]


def yaml_string(text: str) -> str:
    """A YAML double-quoted scalar (JSON string syntax is valid YAML)."""
    return json.dumps(text)


# --------------------------------------------------------------------------------------------
# Simulate mode in lockstep (step_mode: on_command)
# --------------------------------------------------------------------------------------------


def stamp_ns(m):
    """A message's header stamp in integer nanoseconds."""
    return m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec


def joint_command(names, position=(), velocity=()):
    """A ~/joint_commands message: joints by name, as topic_based_ros2_control sends them."""
    from sensor_msgs.msg import JointState

    return JointState(name=list(names), position=[float(x) for x in position], velocity=[float(x) for x in velocity])


def drive(states, pub, message, n):
    """Publishes `message` (or `message(last_state)`) n times, each after the joint state the
    previous one produced on `states`; returns the n joint states. Reliable both ways and matched
    first: no command is resent (in lockstep a resent command would step again)."""
    states.wait_publisher()
    out, last = [], None
    for _ in range(n):
        states.clear()
        pub.publish(message(last) if callable(message) else message)
        last = states.wait(timeout=EVENT_S)[0]
        out.append(last)
    return out
