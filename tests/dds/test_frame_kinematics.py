"""`~/frame_kinematics` over DDS against Pinocchio: link poses, frame Jacobians in the three
references, classical accelerations, the centre of mass, its Jacobian and the mass, on the
default arm (fixed base, every link including those fused through fixed joints) and on Solo12
with a floating base (base pose, twist and acceleration from the request, as
`~/inverse_dynamics` takes them); then bad requests, each refused with success=false, a message
naming the problem and empty arrays, followed by a right answer.

Reference (FrameKinematics.srv / Pinocchio): poses = data.oMf after forwardKinematics; J =
computeFrameJacobian(WORLD | LOCAL | LOCAL_WORLD_ALIGNED), columns named by `columns` (a floating
base's six first, then the joints in the request's order); accelerations =
getFrameClassicalAcceleration in LOCAL for "local", in LOCAL_WORLD_ALIGNED otherwise; mass =
data.mass[0], center_of_mass = data.com[0], its Jacobian = jacobianCenterOfMass.
"""

import numpy as np
import pinocchio as pin
import pytest
from geometry_msgs.msg import Accel, Point, Pose, Quaternion, Twist, Vector3
from spatial_dynamics_msgs.srv import DescribeModel, FrameKinematics

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

FK = "/spatial_dynamics/frame_kinematics"
DM = "/spatial_dynamics/describe_model"
TOL = 1e-12
REFERENCES = {
    "world": pin.ReferenceFrame.WORLD,
    "local": pin.ReferenceFrame.LOCAL,
    "local_world_aligned": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
}


def vec3(x):
    return Vector3(x=float(x[0]), y=float(x[1]), z=float(x[2]))


def pose_msg(p):
    return Pose(position=Point(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(x=p[3], y=p[4], z=p[5], w=p[6]))


def rotation(o):
    """The rotation matrix of a geometry_msgs/Quaternion."""
    return pin.Quaternion(o.w, o.x, o.y, o.z).toRotationMatrix()


def link_names(urdf):
    import xml.etree.ElementTree as ET

    return [link.get("name") for link in ET.parse(urdf).getroot().iter("link")]


def check_answer(resp, ref, names, q, v, a, links, reference):
    """Everything in `resp` against Pinocchio at (q, v, a)."""
    assert resp.success, resp.message
    model, data = ref.model, ref.data
    base_names = [] if ref.base is None else [c for c in resp.columns[:6]]
    assert list(resp.columns) == base_names + list(names)
    cols = [] if ref.base is None else list(range(ref.base.idx_v, ref.base.idx_v + 6))
    cols += [ref.joints[n].idx_v for n in names]
    n = len(cols)
    assert list(resp.links) == list(links)
    pin.forwardKinematics(model, data, q, v, a)
    pin.updateFramePlacements(model, data)
    jacobians = np.asarray(resp.jacobians).reshape(len(links), 6, n) if links else []
    accel_ref = REFERENCES["local" if reference == "local" else "local_world_aligned"]
    for k, link in enumerate(links):
        fid = model.getFrameId(link, pin.FrameType.BODY)
        assert fid < len(model.frames), f"no body frame {link!r} in Pinocchio's model"
        oMf = data.oMf[fid]
        p = resp.poses[k]
        assert_close([p.position.x, p.position.y, p.position.z], oMf.translation, f"{link} position", TOL)
        assert_close(rotation(p.orientation), oMf.rotation, f"{link} orientation", TOL)
        acc = pin.getFrameClassicalAcceleration(model, data, fid, accel_ref)
        got = resp.accelerations[k]
        assert_close(
            [got.linear.x, got.linear.y, got.linear.z, got.angular.x, got.angular.y, got.angular.z],
            np.concatenate([acc.linear, acc.angular]),
            f"{link} acceleration",
            TOL,
        )
        want = pin.computeFrameJacobian(model, data, q, fid, REFERENCES[reference or "local_world_aligned"])
        assert_close(jacobians[k], want[:, cols], f"{link} Jacobian ({reference})", TOL)
    com = pin.centerOfMass(model, data, q)
    assert_close([resp.mass], [data.mass[0]], "mass", TOL)
    assert_close([resp.center_of_mass.x, resp.center_of_mass.y, resp.center_of_mass.z], com, "centre of mass", TOL)
    jcom = pin.jacobianCenterOfMass(model, data, q)
    assert_close(np.asarray(resp.center_of_mass_jacobian).reshape(3, n), jcom[:, cols], "centre-of-mass Jacobian", TOL)


# ---- the default arm ---------------------------------------------------------------------------


@pytest.mark.parametrize("reference", ["world", "local", "local_world_aligned", ""])
def test_arm_every_link_against_pinocchio(arm, ros, ref, reference):
    rng = np.random.default_rng(21)
    links = link_names(sd.DEFAULT_ARM_URDF)
    assert {"flange", "tool0"} <= set(links)  # fused through fixed joints
    for _ in range(3):
        names = list(ARM_JOINTS)
        rng.shuffle(names)
        pos = sd.random_positions(names, rng, sd.DEFAULT_ARM_URDF)
        vel, acc = ([float(x) for x in rng.standard_normal(7)] for _ in range(2))
        req = FrameKinematics.Request(
            name=names, position=pos, velocity=vel, acceleration=acc, links=links, reference=reference
        )
        resp = ros.call(FrameKinematics, FK, req)
        q, v, a = ref.q(names, pos), ref.v(names, vel), ref.v(names, acc)
        check_answer(resp, ref, names, q, v, a, links, reference)


def test_arm_centre_of_mass_alone_and_zero_rates(arm, ros, ref):
    """No links: the centre of mass only; empty velocity and acceleration are zeros."""
    pos = [0.2, -0.4, 0.6, -0.8, 1.0, -1.2, 1.4]
    resp = ros.call(FrameKinematics, FK, FrameKinematics.Request(name=ARM_JOINTS, position=pos))
    assert resp.success, resp.message
    assert len(resp.poses) == 0 and len(resp.jacobians) == 0
    zero = np.zeros(7)
    check_answer(resp, ref, ARM_JOINTS, ref.q(ARM_JOINTS, pos), zero, zero, [], "")
    resp = ros.call(FrameKinematics, FK, FrameKinematics.Request(position=pos, links=["tool0"], reference="local"))
    check_answer(resp, ref, ARM_JOINTS, ref.q(ARM_JOINTS, pos), zero, zero, ["tool0"], "local")


def refused(resp, words):
    assert resp.success is False, f"accepted: {str(resp)[:300]}"
    for word in words:
        assert word in resp.message, f"the reason {resp.message[:300]!r} does not name {word!r}"
    for array in ("links", "poses", "columns", "jacobians", "accelerations", "center_of_mass_jacobian"):
        assert len(getattr(resp, array)) == 0, f"{array} not empty on failure"
    assert resp.mass == 0.0
    assert len(resp.message) < 2000, f"reason of {len(resp.message)} characters"


Q0 = [0.1, -0.2, 0.3, -0.4, 0.5, -0.6, 0.7]
BAD = {
    "unknown link": (dict(links=["tool0", "gripper"]), ["links[1]", "'gripper'", "tool0", "link7"]),
    "huge link name": (dict(links=["x" * 1_000_000]), ["links[0]", "1000000 bytes"]),
    "too many links": (dict(links=["tool0"] * 100_000), ["links has 100000 entries", "at most"]),
    "bad reference": (dict(links=["tool0"], reference="global"), ["reference", "'global'", "local_world_aligned"]),
    "short position": (dict(position=Q0[:6]), ["position has 6 values for 7 names"]),
    "NaN velocity": (dict(velocity=[0.0, float("nan"), 0, 0, 0, 0, 0]), ["velocity", "joint2"]),
    "long acceleration": (dict(acceleration=[0.0] * 8), ["acceleration"]),
    "unknown joint": (dict(name=ARM_JOINTS[:6] + ["elbow"]), ["'elbow'"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_requests_are_refused_then_served(arm, ros, ref, case):
    fields, words = BAD[case]
    request = dict(name=ARM_JOINTS, position=Q0)
    request.update(fields)
    refused(ros.call(FrameKinematics, FK, FrameKinematics.Request(**request)), words)
    resp = ros.call(FrameKinematics, FK, FrameKinematics.Request(name=ARM_JOINTS, position=Q0, links=["link4"]))
    zero = np.zeros(7)
    check_answer(resp, ref, ARM_JOINTS, ref.q(ARM_JOINTS, Q0), zero, zero, ["link4"], "")


# ---- Solo12, floating base ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def solo(module_nodes, ros, arm):
    """Solo12 beside the arm, in its own namespace (so the arm's module-scoped node stays)."""
    node = module_nodes.start(
        "-r", "__ns:=/solo", "-p", f"urdf_file:={sd.solo12_urdf()}", "-p", "floating_base:=true", label="solo12"
    )
    ros.wait_for_service(DescribeModel, "/solo/spatial_dynamics/describe_model")
    return node


def test_floating_base_against_pinocchio(solo, ros):
    urdf = sd.solo12_urdf()
    ref = sd.PinRef(urdf, floating=True)
    joints = [j[0] for j in sd.urdf_joints(urdf)]
    links = link_names(urdf)
    rng = np.random.default_rng(22)
    for reference in ("world", "local", "local_world_aligned"):
        names = list(joints)
        rng.shuffle(names)
        pos = sd.random_positions(names, rng, urdf)
        vel, acc = ([float(x) for x in rng.standard_normal(len(names))] for _ in range(2))
        quat = rng.standard_normal(4)
        quat /= np.linalg.norm(quat)
        base = [float(x) for x in np.concatenate([rng.uniform(-1, 1, 3), quat])]
        twist, accel = (rng.standard_normal(6) for _ in range(2))
        req = FrameKinematics.Request(
            name=names,
            position=pos,
            velocity=vel,
            acceleration=acc,
            base_pose=pose_msg(base),
            base_twist=Twist(linear=vec3(twist[:3]), angular=vec3(twist[3:])),
            base_accel=Accel(linear=vec3(accel[:3]), angular=vec3(accel[3:])),
            links=links,
            reference=reference,
        )
        resp = ros.call(FrameKinematics, "/solo/spatial_dynamics/frame_kinematics", req)
        assert resp.success, resp.message
        assert [c.split("/")[-1] for c in resp.columns[:6]] == [
            "linear_x", "linear_y", "linear_z", "angular_x", "angular_y", "angular_z"
        ]
        q = ref.q(names, pos, base)
        v, a = ref.v(names, vel, twist), ref.v(names, acc, accel)
        check_answer(resp, ref, names, q, v, a, links, reference)


# ---- A pan-tilt head whose moving links have no mass ---------------------------------------------

PAN_TILT = """<?xml version="1.0"?>
<robot name="pan_tilt">
  <link name="base"><inertial><mass value="3"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="pan" type="revolute"><parent link="base"/><child link="pan_link"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="pan_link"/>
  <joint name="tilt" type="revolute"><parent link="pan_link"/><child link="tilt_link"/><origin xyz="0 0 0.05"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="tilt_link"/>
  <joint name="cam" type="fixed"><parent link="tilt_link"/><child link="camera"/><origin xyz="0.1 0 0"/></joint>
  <link name="camera"/>
</robot>
"""


def test_massless_moving_links_still_have_frames(nodes, ros, tmp_path):
    """No moving body has mass: the centre of mass is answered as mass 0 (at the origin, a zero
    Jacobian) and the links are served; the camera sits at (0, 0, 0.15) + R_z(pan) R_y(tilt) (0.1, 0, 0)."""
    urdf = tmp_path / "pan_tilt.urdf"
    urdf.write_text(PAN_TILT)
    nodes.start("-r", "__ns:=/head", "-p", f"urdf_file:={urdf}", label="pan-tilt")
    ros.wait_for_service(DescribeModel, "/head/spatial_dynamics/describe_model")
    pan, tilt = 0.4, -0.3
    req = FrameKinematics.Request(name=["pan", "tilt"], position=[pan, tilt], links=["camera"], reference="world")
    resp = ros.call(FrameKinematics, "/head/spatial_dynamics/frame_kinematics", req)
    assert resp.success, resp.message
    assert resp.mass == 0.0 and list(resp.center_of_mass_jacobian) == [0.0] * 6
    expected = np.array([0, 0, 0.15]) + 0.1 * np.array(
        [np.cos(pan) * np.cos(tilt), np.sin(pan) * np.cos(tilt), -np.sin(tilt)]
    )
    p = resp.poses[0].position
    assert_close([p.x, p.y, p.z], expected, "camera position", tol=1e-15)
