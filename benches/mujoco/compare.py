"""Simulation steps per second, ours against MuJoCo, on the same URDF, integrator and step.

Run by launch_scripts/bench_mujoco.sh (which builds the C driver benches/mujoco/steps.c):

    compare.py --ours BIN --mujoco-steps BIN --robots DIR --work DIR [--steps N] [--repeats R]
               [--rounds K]

Per robot (UR5 fixed; Solo12 on a floating base) and integrator (RK4, semi-implicit Euler, 1 ms):
ours through `spatial_dynamics bench --kernels sim_<integrator>`, MuJoCo through mj_step in C,
both timed inside their process over runs of N steps with no output, the median of R repeats,
in K rounds that alternate ours and MuJoCo's: a run of 1000 steps lasts about a millisecond, and
on a shared or virtual machine the rate of either moves by tens of percent within seconds, so
the ratio reported is the median of each round's own ratio, taken a moment apart, and beside it
each side's fastest round against the other's (a VM whose speed switches between levels can time
the two sides of one round at different levels).
Both start from the same non-trivial state (joints displaced and moving; the floating base
translating and spinning) under gravity with zero commands, no contact, limits or damping.

The end states after N steps are compared in the tangent space: joint angle and velocity
differences, and for the free joint the position, the rotation angle of q_ours⁻¹ q_mujoco, and
the velocity in our convention ([v_B; ω_B] in the base frame; MuJoCo's qvel is [R v_B; ω_B]).
The run fails when a joint's difference exceeds --tolerance (1e-9): on revolute joints both
simulators use the same schemes. The free joint's differences are reported, not asserted: the
schemes differ there. Our Euler moves the base along the SE(3) exponential of its body twist,
MuJoCo's adds h·v_world to the position and rotates by h·ω_B: the same continuous dynamics,
different first-order schemes, so their trajectories differ by O(h). Both RK4s are of order 4 for
the base pose: ours takes the stages on SE(3) (Munthe-Kaas: body twists carried back by dexp⁻¹),
MuJoCo's integrates the position in world coordinates, where the stages combine as in R³; their
error constants differ, and at 1 ms both are at rounding level. The rotation angle below comes
from acos, which cannot resolve angles under about 3e-8 rad.
"""

import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

ROBOTS = [  # name, URDF under example-robot-data's robots/, floating
    ("UR5", "ur_description/urdf/ur5_robot.urdf", False),
    ("Solo12", "solo_description/robots/solo12.urdf", True),
]
INTEGRATORS = [("rk4", "rk4"), ("semi_implicit_euler", "euler")]  # ours, MuJoCo's
MUJOCO_COMPILER = dict(discardvisual="true", balanceinertia="false", inertiafromgeom="false",
                       fusestatic="true", strippath="true")


def mujoco_urdf(src, dst, floating):
    """The URDF as MuJoCo should read it: no visuals, collisions or joint dynamics (damping,
    friction), the compiler options that keep the URDF's inertias and fuse fixed joints as we
    do, and for a floating robot a `floating` joint (MuJoCo's free joint) above the root."""
    tree = ET.parse(src)
    robot = tree.getroot()
    for parent in list(robot.iter()):
        for child in list(parent):
            if child.tag in ("visual", "collision", "dynamics", "transmission", "gazebo"):
                parent.remove(child)
    ET.SubElement(ET.SubElement(robot, "mujoco"), "compiler", MUJOCO_COMPILER)
    if floating:
        children = {j.find("child").get("link") for j in robot.iter("joint")}
        root = next(l.get("name") for l in robot.iter("link") if l.get("name") not in children)
        ET.SubElement(robot, "link", name="mujoco_world")
        joint = ET.SubElement(robot, "joint", name="root_joint", type="floating")
        ET.SubElement(joint, "parent", link="mujoco_world")
        ET.SubElement(joint, "child", link=root)
    tree.write(dst)


def initial_state(joints):
    """Our (q, v): joint k at 0.3 sin(k + 1) rad moving at 0.8 cos(k + 1) rad/s; a floating base
    0.5 m up, rotated 0.4 rad about (1, 2, 3)/|.|, with v_B = (0.1, -0.2, 0.3) m/s and
    ω_B = (0.4, -0.3, 0.5) rad/s."""
    q, v = [], []
    for k, j in enumerate(joints):
        if j["type"] == "floating":
            axis = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
            s, c = math.sin(0.2), math.cos(0.2)
            q += [0.0, 0.0, 0.5, *(s * axis), c]  # x y z, qx qy qz qw
            v += [0.1, -0.2, 0.3, 0.4, -0.3, 0.5]
        elif j["nq"] == 1:
            q.append(0.3 * math.sin(k + 1))
            v.append(0.8 * math.cos(k + 1))
        else:
            sys.exit(f"compare.py: joint {j['name']} of type {j['type']}: not mapped to MuJoCo")
    return q, v


def quat_rotate(wxyz, x):
    """R(q) x for a unit quaternion (w, x, y, z)."""
    w, u = wxyz[0], np.asarray(wxyz[1:])
    return x + 2.0 * np.cross(u, np.cross(u, x) + w * x)


def to_mujoco(m, joints, q, v):
    """Our (q, v) in MuJoCo's qpos, qvel."""
    qpos, qvel = np.zeros(m.nq), np.zeros(m.nv)
    for j in joints:
        mj = m.joint(j["name"])
        a, d = mj.qposadr[0], mj.dofadr[0]
        qi, vi = j["q_index"], j["v_index"]
        if j["type"] == "floating":
            x, y, z, qx, qy, qz, qw = q[qi:qi + 7]
            qpos[a:a + 7] = [x, y, z, qw, qx, qy, qz]
            qvel[d:d + 3] = quat_rotate([qw, qx, qy, qz], np.array(v[vi:vi + 3]))
            qvel[d + 3:d + 6] = v[vi + 3:vi + 6]
        else:
            qpos[a], qvel[d] = q[qi], v[vi]
    return qpos, qvel


def differences(m, joints, q, v, qpos, qvel):
    """max |Δ| over the joints' positions (tangent) and velocities, ours against MuJoCo's,
    separately for the free joint: {"joints": (dq, dv), "free": (dq, dv)}."""
    out = {"joints": [0.0, 0.0], "free": [0.0, 0.0]}
    for j in joints:
        mj = m.joint(j["name"])
        a, d = mj.qposadr[0], mj.dofadr[0]
        qi, vi = j["q_index"], j["v_index"]
        if j["type"] == "floating":
            x, y, z, qx, qy, qz, qw = q[qi:qi + 7]
            ours = np.array([qw, qx, qy, qz])
            theirs = np.asarray(qpos[a + 3:a + 7])
            angle = 2.0 * math.acos(min(1.0, abs(float(ours @ theirs))))
            dq = max(np.max(np.abs(np.array([x, y, z]) - qpos[a:a + 3])), angle)
            # MuJoCo's linear velocity back into the base frame: R⁻¹ v_world.
            inv = theirs * np.array([1.0, -1.0, -1.0, -1.0])
            v_body = quat_rotate(inv, np.asarray(qvel[d:d + 3]))
            dv = max(np.max(np.abs(np.array(v[vi:vi + 3]) - v_body)),
                     np.max(np.abs(np.array(v[vi + 3:vi + 6]) - qvel[d + 3:d + 6])))
            out["free"] = [max(out["free"][0], dq), max(out["free"][1], dv)]
        else:
            out["joints"] = [max(out["joints"][0], abs(q[qi] - qpos[a])),
                             max(out["joints"][1], abs(v[vi] - qvel[d]))]
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ours", required=True)
    p.add_argument("--mujoco-steps", required=True)
    p.add_argument("--robots", required=True)
    p.add_argument("--work", required=True)
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--dt", type=float, default=1e-3)
    p.add_argument("--tolerance", type=float, default=1e-9)
    args = p.parse_args()

    rows, failures = [], []
    for name, rel, floating in ROBOTS:
        urdf = os.path.join(args.robots, rel)
        mj_urdf = os.path.join(args.work, f"{name}.urdf")
        mujoco_urdf(urdf, mj_urdf, floating)
        m = mujoco.MjModel.from_xml_path(mj_urdf)
        model_args = ["--urdf", urdf] + (["--floating-base"] if floating else [])
        info = json.loads(subprocess.run([args.ours, "model", "--json", *model_args],
                                         check=True, capture_output=True, text=True).stdout)
        joints = info["joints"]
        if (m.nq, m.nv) != (info["nq"], info["nv"]):
            sys.exit(f"compare.py: {name}: MuJoCo has nq, nv = {m.nq}, {m.nv}, "
                     f"we have {info['nq']}, {info['nv']}")
        q0, v0 = initial_state(joints)
        qpos0, qvel0 = to_mujoco(m, joints, q0, v0)
        state_file = os.path.join(args.work, f"{name}.state")
        with open(state_file, "w") as f:
            f.write(" ".join(repr(float(x)) for x in [*qpos0, *qvel0]) + "\n")
        for ours_name, mj_name in INTEGRATORS:
            kernel = f"sim_{ours_name}"
            ours_ns, theirs_ns, ratios = [], [], []
            for _ in range(args.rounds):
                ours = json.loads(subprocess.run(
                    [args.ours, "bench", *model_args, "--json", "--kernels", kernel,
                     "--repeats", str(args.repeats), "--sim-steps", str(args.steps),
                     "--sim-dt", repr(args.dt), "--sim-initial", json.dumps({"q": q0, "v": v0})],
                    check=True, capture_output=True, text=True).stdout)
                theirs = json.loads(subprocess.run(
                    [args.mujoco_steps, mj_urdf, mj_name, repr(args.dt), str(args.steps),
                     str(args.repeats), state_file],
                    check=True, capture_output=True, text=True).stdout)
                ours_ns.append(ours["ns_per_call"][kernel])
                theirs_ns.append(theirs["ns_per_step"])
                ratios.append(theirs_ns[-1] / ours_ns[-1])
            end = ours["sim_end"][kernel]
            diff = differences(m, joints, end["q"], end["v"], theirs["qpos"], theirs["qvel"])
            if max(diff["joints"]) > args.tolerance:
                failures.append(f"{name} {ours_name}: joints differ by {max(diff['joints']):.3g}")
            ns_ours, ns_mj = statistics.median(ours_ns), statistics.median(theirs_ns)
            # Each simulator's fastest round against the other's: on a VM whose speed switches
            # between levels, one round can time the two at different levels.
            fastest = min(theirs_ns) / min(ours_ns)
            rows.append((name + (" (floating)" if floating else ""), info["nv"], ours_name,
                         1e9 / ns_ours, 1e9 / ns_mj, statistics.median(ratios), fastest, diff,
                         floating))
            print(f"== {name} {ours_name} done", file=sys.stderr)

    t = args.steps * args.dt
    print(f"| robot | nv | integrator | ours (steps/s) | MuJoCo (steps/s) | ours / MuJoCo "
          f"| fastest rounds | max Δq after {t:g} s | max Δv after {t:g} s |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for robot, nv, integ, ours, theirs, ratio, fastest, diff, floating in rows:
        dq, dv = diff["joints"]
        cell = lambda x: f"{x:.1e}"
        dq_s, dv_s = cell(dq), cell(dv)
        if floating:
            dq_s += f"; base {cell(diff['free'][0])} (not asserted)"
            dv_s += f"; base {cell(diff['free'][1])}"
        print(f"| {robot} | {nv} | {integ} | {ours:,.0f} | {theirs:,.0f} | {ratio:.2f} "
              f"| {fastest:.2f} | {dq_s} | {dv_s} |")
    print()
    print(f"MuJoCo {mujoco.__version__}; {args.steps} steps of {args.dt:g} s per run, median of "
          f"{args.repeats} runs, in {args.rounds} rounds of ours then MuJoCo's: the rates are the "
          f"medians over the rounds, the ratio the median of each round's own ratio, the fastest rounds' "
          f"ratio each simulator's least time over the rounds against the other's; Δ: ours against MuJoCo's end state (joint rad, rad/s; base: m or "
          f"rad, m/s or rad/s, in our base frame); the run fails when a joint's Δ exceeds "
          f"{args.tolerance:g}.")
    if failures:
        print("bench_mujoco: trajectories differ beyond the tolerance "
              f"{args.tolerance:g}: " + "; ".join(failures), file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
