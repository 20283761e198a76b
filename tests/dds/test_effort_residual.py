"""~/effort_residual on the live node (default arm), against Pinocchio.

A burst of joint states along q_j(t) = A_j sin(w_j t + p_j), stamped 2 ms apart (header stamps:
the node's time base for the differences), each with ``effort = pin.rnea(q, q̇, q̈_exact) +
τ_ext``. The node publishes joint state i's residual when joint state i + 1 has arrived, stamped
with joint state i's stamp. Checked for each residual:

* stamp, frame, names, positions and velocities are joint state i's;
* ``effort = τ_i − pin.rnea(q_i, q̇_i, q̈_i)``, q̈_i the documented three-point difference of the
  velocities (one-sided at the first joint state) over the joint states the node answered (its
  ``~/gravity_effort`` answers say which);
* it recovers τ_ext within ``Σ_k |M_jk| · h²/6 · A_k w_k⁴`` (the three-point error bound, see
  tests/python/test_replay_residual.py).

The newest joint state has no residual yet; a joint state with a short effort array gets none and
is counted on /diagnostics under ``~/effort_residual dropped``; one without effort gets none, quietly.
"""

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS, assert_close

GRAVITY = "/spatial_dynamics/gravity_effort"
RESIDUAL = "/spatial_dynamics/effort_residual"
AMP = np.array([0.5, 0.4, 0.6, 0.3, 0.5, 0.4, 1.0])
OMEGA = np.array([2.0, 3.0, 1.5, 2.5, 3.0, 2.0, 1.0])
PHASE = np.array([0.1, 0.7, -0.3, 1.2, 0.0, -1.0, 2.0])
STEP_NS = 2_000_000
EXT = np.array([0.0, 4.0, 0.0, 0.0, -1.5, 0.0, 0.0])


def motion(t):
    s = OMEGA * t + PHASE
    return AMP * np.sin(s), AMP * OMEGA * np.cos(s), -AMP * OMEGA**2 * np.sin(s)


def ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def test_effort_residual_one_sample_late_matches_pinocchio(arm, ros, ref):
    from builtin_interfaces.msg import Time

    gravity = ros.collector(JointState, GRAVITY)
    residual = ros.collector(JointState, RESIDUAL)
    diag = ros.collector(DiagnosticArray, "/diagnostics")
    for c in (gravity, residual):
        c.wait_publisher()
    pub = ros.publisher(JointState, "/joint_states", sd.qos_reliable(100))
    names = list(reversed(ARM_JOINTS))
    order = [ARM_JOINTS.index(n) for n in names]

    def message(t_ns, effort="ok"):
        q, v, a = motion(t_ns * 1e-9 - 1000.0)
        tau = ref.pick(ref.rnea(ref.q(ARM_JOINTS, q), ref.v(ARM_JOINTS, v), ref.v(ARM_JOINTS, a)), ARM_JOINTS) + EXT
        msg = JointState(name=names, position=list(q[order]), velocity=list(v[order]))
        msg.effort = [] if effort == "none" else list(tau[order][: 6 if effort == "short" else 7])
        msg.header.stamp = Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
        msg.header.frame_id = "arm_base"
        return msg, q, v, tau

    # Warm up until the node answers this publisher (the first samples of a new writer can be lost).
    t0 = 1000 * 1_000_000_000 + sd.fresh_stamp().sec * 10_000_000  # unique to this test run
    warm = [t0 - 1_000_000_000]  # a second before the burst: not differenced across
    ros.exchange(
        lambda: (warm.append(warm[-1] + 1), pub.publish(message(warm[-1], "none")[0]), ros.spin_for(0.02)),
        gravity,
        lambda m: ns(m.header.stamp) in warm,
    )
    sent = {}
    n = 40
    for i in range(n):
        t = t0 + i * STEP_NS + (i % 3) * 100_000
        kind = "short" if i == 20 else "none" if i == 25 else "ok"
        msg, q, v, tau = message(t, kind)
        sent[t] = dict(q=q, v=v, tau=tau, kind=kind)
        pub.publish(msg)
        ros.spin_for(0.005)
    times = sorted(sent)
    ros.spin_until(lambda: sum(ns(m.header.stamp) in sent for m in gravity.messages) == n, sd.EVENT_S)
    answered = sorted({ns(m.header.stamp) for m in gravity.messages} & set(sent))
    assert len(answered) >= n - 2, f"only {len(answered)} of {n} joint states answered"
    with_effort = [t for t in answered[:-1] if sent[t]["kind"] == "ok"]
    ros.spin_until(lambda: sum(ns(m.header.stamp) in sent for m in residual.messages) >= len(with_effort), sd.EVENT_S)
    ros.spin_for(0.3)
    got = {ns(m.header.stamp): m for m in residual.messages if ns(m.header.stamp) in sent}
    assert set(got) == set(with_effort), (sorted(set(got) ^ set(with_effort)))
    assert answered[-1] not in got  # the newest waits for its successor

    for k, t in enumerate(answered[:-1]):
        if t not in got:
            continue
        m, s = got[t], sent[t]
        assert m.header.frame_id == "arm_base" and list(m.name) == names
        assert_close(m.position, s["q"][order], "position echo", tol=0)
        assert_close(m.velocity, s["v"][order], "velocity echo", tol=0)
        v = s["v"]
        if k == 0:  # first of its segment: forward difference
            hp = (answered[1] - t) * 1e-9
            a = (sent[answered[1]]["v"] - v) / hp
            e = hp / 2 * AMP * OMEGA**3
        else:
            tm, tp = answered[k - 1], answered[k + 1]
            hm, hp = (t - tm) * 1e-9, (tp - t) * 1e-9
            vm, vp = sent[tm]["v"], sent[tp]["v"]
            a = (hm**2 * (vp - v) + hp**2 * (v - vm)) / (hm * hp * (hm + hp))
            e = hm * hp / 6 * AMP * OMEGA**4
        qp = ref.q(ARM_JOINTS, s["q"])
        want = s["tau"] - ref.pick(ref.rnea(qp, ref.v(ARM_JOINTS, v), ref.v(ARM_JOINTS, a)), ARM_JOINTS)
        assert_close(m.effort, want[order], f"residual at joint state {k}", tol=1e-9)
        M = np.asarray(ref.crba(qp))
        Mj = ref.matrix(M, ARM_JOINTS)
        bound = np.abs(Mj) @ (e + 4e-16 * np.abs(v).max() / 1e-3) + 1e-9 * (1 + np.abs(s["tau"]))
        err = np.abs(np.asarray(m.effort) - EXT[order])
        assert np.all(err <= bound[order]), (k, err, bound[order])

    # The short effort array was counted against ~/effort_residual.
    def counted(msg):
        values = sd.status_values(msg, "spatial_dynamics: dynamics")
        return sd.dropped_count(values, RESIDUAL) >= 1

    diag.wait(1, timeout=sd.EVENT_S, predicate=counted)
