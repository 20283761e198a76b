"""`spatial_dynamics replay`: ``~/effort_residual`` and ``~/commands`` (Float64MultiArray), against
Pinocchio on bags written by rosbags.

Residual. The default arm follows q_j(t) = A_j sin(w_j t + p_j) (closed-form q̇, q̈ and every
higher derivative), sampled at about 1 kHz on uneven steps. Each joint state's ``effort`` is
``pin.rnea(q, q̇, q̈_exact) + τ_ext(t)``, τ_ext a 5 N·m step on joint2 halfway through and a slow
sinusoid on joint5. The replay's residual ``τ_measured − RNEA(q, q̇, q̈_fd)`` must recover τ_ext
within a bound derived from the finite-difference error (no number of ours pasted in):

RNEA is affine in q̈ with slope M(q), so ``r − τ_ext = M(q) (q̈_exact − q̈_fd)``. The three-point
slope on steps h₋, h₊ (Taylor with a third-order remainder on both sides) errs by at most
``h₋ h₊ / 6 · max|q̇'''|`` per joint, the one-sided differences at segment ends by
``h / 2 · max|q̇''|``; here ``max|q̇'''_j| = A_j w_j⁴`` and ``max|q̇''_j| = A_j w_j³``. So, joint by
joint, ``|r_j − τ_ext,j| ≤ Σ_k |M_jk(q)| e_k`` with e_k that derivative bound plus the rounding of
the difference quotient (``4 ε |q̇| / h``), M from ``pin.crba``. The test also measures
the error against RNEA with the exact q̈ and checks the bound is not vacuous (far below the step).

The residual is also checked message by message against ``τ_measured − pin.rnea(q, q̇, q̈_fd)``
with q̈_fd the documented scheme computed here (``test_replay.expected_accelerations``).
Joint states without effort get no residual (not counted); a short or non-finite effort loses
the residual only (counted under ``no_residual``, kind ``bad effort``).

Commands. Float64MultiArray on ``/spatial_dynamics/commands`` in ``--command-joints`` order,
interleaved with JointState effort commands: ``~/acceleration`` is ``pin.aba(q, q̇, τ)`` under the
latest command of either kind (joints a Float64MultiArray leaves out get zero).
"""

import numpy as np
import pinocchio as pin

from test_replay import (
    JOINTS,
    JS,
    NODE,
    TS,
    URDF,
    Pin,
    cdr,
    close,
    expected_accelerations,
    read_output,
    replay,
    stamp_ns,
    state_msg,
    write_bag,
)

F64MA = "std_msgs/msg/Float64MultiArray"
Float64MultiArray = TS.types[F64MA]
MultiArrayLayout = TS.types["std_msgs/msg/MultiArrayLayout"]
MultiArrayDimension = TS.types["std_msgs/msg/MultiArrayDimension"]

AMP = np.array([0.5, 0.4, 0.6, 0.3, 0.5, 0.4, 1.0])
OMEGA = np.array([2.0, 3.0, 1.5, 2.5, 3.0, 2.0, 1.0])
PHASE = np.array([0.1, 0.7, -0.3, 1.2, 0.0, -1.0, 2.0])
T0 = 1_700_000_000_000_000_000
EPS = np.finfo(float).eps


def motion(t):
    s = OMEGA * t + PHASE
    return AMP * np.sin(s), AMP * OMEGA * np.cos(s), -AMP * OMEGA**2 * np.sin(s)


def tau_ext(t, t_step):
    e = np.zeros(7)
    e[1] = 5.0 if t >= t_step else 0.0
    e[4] = 0.8 * np.sin(0.7 * t)
    return e


def residual_bag(n=3000, seed=11):
    rng = np.random.default_rng(seed)
    urdf_text = URDF.read_text()
    ref = Pin(urdf_text)
    t, records, states = T0, [], []
    t_step = None
    bad = 0
    for k in range(n):
        t += 1_000_000 + int(rng.integers(-200_000, 200_000))  # 1 ms ± 0.2 ms
        if k == 1600:
            t += 300_000_000  # a gap: a new segment (one-sided differences at both ends)
        ts = (t - T0) * 1e-9
        if k == n // 2:
            t_step = ts
        q, v, a = motion(ts)
        ext = tau_ext(ts, t_step if t_step is not None else np.inf)
        qp, vp = ref.q(dict(zip(JOINTS, q))), ref.v(dict(zip(JOINTS, v)))
        tau = ref.named(pin.rnea(ref.model, ref.data, qp, vp, ref.v(dict(zip(JOINTS, a)))), JOINTS) + ext
        names = JOINTS if k % 2 else JOINTS[::-1]
        order = [JOINTS.index(j) for j in names]
        msg = state_msg(t, names, q[order], v[order])
        kind = "effort"
        if k % 250 == 7:
            kind = "none"  # no effort: no residual, nothing counted
        elif k % 400 == 13:
            kind = "short"
            msg.effort = tau[order][:-1]
        elif k % 400 == 213:
            kind = "nan"
            e = tau[order].copy()
            e[3] = np.nan
            msg.effort = e
        if kind == "effort":
            msg.effort = tau[order]
        bad += kind in ("short", "nan")
        log = t + 500_000
        records.append(("/joint_states", JS, log, cdr(msg)))
        states.append(dict(log=log, t=t, names=list(names), q=q, v=v, has_v=True, a=a, tau=tau, ext=ext, kind=kind))
    return records, states, bad, ref


def test_residual_recovers_the_external_torque_within_the_finite_difference_bound(tmp_path):
    records, states, bad, ref = residual_bag()
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    summary, stderr = replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm")
    got = read_output(tmp_path / "out.mcap")
    residuals = got[NODE + "/effort_residual"]
    assert residuals[0][2] == JS
    # Every joint state answered; residuals for those with a valid effort only.
    assert summary["written"][NODE + "/gravity_effort"] == len(states)
    with_effort = [s for s in states if s["kind"] == "effort"]
    assert len(residuals) == summary["written"][NODE + "/effort_residual"] == len(with_effort)
    no = summary["no_residual"]
    assert no["total"] == bad and no["kinds"]["bad effort"]["count"] == bad, stderr
    assert summary["skipped"]["/joint_states"]["total"] == 0

    fd = dict(zip((s["log"] for s in states), expected_accelerations(states)))
    worst_ratio, worst_err, worst_exact, step_seen = 0.0, 0.0, 0.0, False
    kinds = set()
    for s, (log, r, _) in zip(with_effort, residuals):
        assert log == s["log"] and stamp_ns(r.header) == s["t"] and r.header.frame_id == "base"
        assert list(r.name) == s["names"]
        order = [JOINTS.index(j) for j in s["names"]]
        assert np.array_equal(r.position, s["q"][order]) and np.array_equal(r.velocity, s["v"][order])
        kind, a_fd = fd[log]
        kinds.add(kind)
        q, v = ref.q(dict(zip(JOINTS, s["q"]))), ref.v(dict(zip(JOINTS, s["v"])))
        # Message by message: τ − pin.rnea(q, q̇, q̈_fd), q̈_fd by the documented scheme.
        want = s["tau"] - ref.named(pin.rnea(ref.model, ref.data, q, v, ref.v(dict(zip(JOINTS, a_fd)))), JOINTS)
        assert close(r.effort, want[order], 1e-9), (r.effort, want[order])
        # Against the external torque: within the derived bound.
        i = states.index(s)
        if kind == "central":
            hm, hp = (s["t"] - states[i - 1]["t"]) * 1e-9, (states[i + 1]["t"] - s["t"]) * 1e-9
            e = hm * hp / 6 * AMP * OMEGA**4 + 4 * EPS * np.abs(s["v"]).max() / min(hm, hp)
        else:
            h = (s["t"] - states[i - 1]["t"] if kind == "backward" else states[i + 1]["t"] - s["t"]) * 1e-9
            e = h / 2 * AMP * OMEGA**3 + 4 * EPS * np.abs(s["v"]).max() / h
        M = pin.crba(ref.model, ref.data, q)
        M = np.triu(M) + np.triu(M, 1).T
        Mj = np.array([[M[ref.v_of[a], ref.v_of[b]] for b in JOINTS] for a in JOINTS])
        bound = np.abs(Mj) @ e + 1e-9 * (1 + np.abs(s["tau"]))
        err = np.abs(np.asarray(r.effort) - s["ext"][order])
        assert np.all(err <= bound[order]), (kind, err, bound[order])
        # The same error measured against RNEA with the exact q̈ (what the bound bounds).
        exact = s["tau"] - ref.named(pin.rnea(ref.model, ref.data, q, v, ref.v(dict(zip(JOINTS, s["a"])))), JOINTS)
        assert np.allclose(exact, s["ext"], atol=1e-9)
        if kind == "central":
            worst_ratio = max(worst_ratio, (err / bound[order]).max())
            worst_err, worst_exact = max(worst_err, err.max()), max(worst_exact, bound.max())
        step_seen |= s["ext"][1] == 5.0
    assert kinds == {"central", "forward", "backward"} and step_seen
    # Not vacuous: inside segments the bound is far below the 5 N·m step (about 1e-4 N·m at 1 kHz).
    assert worst_exact < 1e-3, worst_exact
    print(f"central: max |r - tau_ext| = {worst_err:.3g} N·m, max bound = {worst_exact:.3g} N·m, worst err/bound = {worst_ratio:.3f}")


def multi_array(values, labels=True):
    dim = [MultiArrayDimension(label="joints", size=len(values), stride=len(values))] if labels else []
    return Float64MultiArray(layout=MultiArrayLayout(dim=dim, data_offset=0), data=np.asarray(values, dtype=float))


def test_float64_multi_array_commands_drive_the_acceleration(tmp_path):
    """Float64MultiArray commands in --command-joints order and JointState effort commands, the
    latest of either kind held: ~/acceleration is pin.aba under it."""
    rng = np.random.default_rng(5)
    cmd_joints = ["joint3", "joint1", "joint6", "joint2"]
    records, states, cmds = [], [], []
    t = T0
    bad = 0
    for k in range(600):
        t += 2_000_000
        q, v, _ = motion((t - T0) * 1e-9)
        log = t + 400_000
        records.append(("/joint_states", JS, log, cdr(state_msg(t, JOINTS, q, v))))
        states.append(dict(log=log, q=q, v=v))
        if k % 7 == 2:
            values = rng.normal(0, 4, len(cmd_joints))
            records.append((NODE + "/commands", F64MA, log + 10_000, cdr(multi_array(values, k % 2 == 0), F64MA)))
            tau = {j: 0.0 for j in JOINTS} | dict(zip(cmd_joints, values))
            cmds.append((log + 10_000, tau))
        if k % 23 == 5:
            tau = {j: float(x) for j, x in zip(JOINTS, rng.normal(0, 4, 7))}
            cmd = state_msg(t, JOINTS, [], [])
            cmd.effort = np.array([tau[j] for j in JOINTS])
            records.append((NODE + "/effort_command", JS, log + 20_000, cdr(cmd)))
            cmds.append((log + 20_000, tau))
        if k % 97 == 50:
            # Wrong length, then a NaN: skipped, counted, the previous command holds.
            records.append((NODE + "/commands", F64MA, log + 30_000, cdr(multi_array(np.ones(5)), F64MA)))
            records.append((NODE + "/commands", F64MA, log + 40_000, cdr(multi_array([1, np.nan, 0, 0]), F64MA)))
            bad += 2
    bag = tmp_path / "in"
    write_bag(bag, "mcap", records)
    summary, stderr = replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm", "--command-joints", ",".join(cmd_joints))
    key = NODE + "/commands"
    assert summary["read"][key] == sum(1 for r in records if r[0] == key)
    skipped = summary["skipped"][key]
    assert skipped["total"] == bad and set(skipped["kinds"]) == {"wrong length", "bad value"}, stderr
    accel = read_output(tmp_path / "out.mcap")[NODE + "/acceleration"]
    assert len(accel) == len(states)
    ref = Pin(URDF.read_text())
    ci, tau_cmd, commanded = 0, {j: 0.0 for j in JOINTS}, 0
    for s, (log, a, _) in zip(states, accel):
        while ci < len(cmds) and cmds[ci][0] <= s["log"]:
            tau_cmd = cmds[ci][1]
            ci += 1
        commanded += any(tau_cmd.values())
        q, v = ref.q(dict(zip(JOINTS, s["q"]))), ref.v(dict(zip(JOINTS, s["v"])))
        qdd = pin.aba(ref.model, ref.data, q, v, ref.v(tau_cmd))
        assert close(a.acceleration, ref.named(qdd, JOINTS), 1e-9)
        assert np.array_equal(a.effort, [tau_cmd[j] for j in JOINTS])
    assert commanded > len(states) // 2

    # An unknown joint in --command-joints is refused, naming it.
    import subprocess

    from test_replay import BIN

    run = subprocess.run(
        [BIN, "replay", "--bag", str(bag), "--out", str(tmp_path / "o.mcap"), "--builtin", "default_arm", "--command-joints", "joint1,elbow"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode != 0 and "--command-joints: unknown joint 'elbow'" in run.stderr, run.stderr
