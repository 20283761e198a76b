"""`~/linearize` over DDS: the continuous and discrete A, B of the default arm against Pinocchio's
computeABADerivatives (and, for a floating base, the SE(3) corner -ad(v) and pin.dIntegrate
composed by hand); bad requests refused; and a controller that proves it: a discrete LQR designed
from the service's one-step map holds the arm, in the node's simulate mode, at a pose away from
the gravity equilibrium from a perturbed start, and the same design from central finite
differences of `~/forward_dynamics` gives the same gain.

Reference (Linearize.srv): x = [q; v] on the tangent, u = tau; continuous
A = [-ad(v) I; ddq_dq ddq_dv], B = [0; Minv]; with dt = h > 0 one semi-implicit Euler step,
A = [Dq + h^2 Dv ddq_dq, h Dv (I + h ddq_dv); h ddq_dq, I + h ddq_dv], B = [h^2 Dv Minv; h Minv],
Dq, Dv = pin.dIntegrate(q, h v+) (ARG0, ARG1) with v+ = v + h qdd.
"""

import numpy as np
import pinocchio as pin
import pytest
from geometry_msgs.msg import Point, Pose, Quaternion, Twist, Vector3, Wrench
from sensor_msgs.msg import JointState
from spatial_dynamics_msgs.srv import DescribeModel, ForwardDynamics, InverseDynamics, Linearize, Reset
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool

import sd_dds_support as sd
from sd_dds_support import ARM_JOINTS

NODE = "/spatial_dynamics"
LIN = f"{NODE}/linearize"
FLOATING = "/floating/spatial_dynamics/linearize"
TOL = 1e-10

# The controller's operating point: the arm held out against gravity (g(q0) up to 16 N*m).
Q0 = np.array([0.1, 0.7, -0.2, -1.1, 0.3, 0.5, 0.0])
START = Q0 + np.array([0.05, -0.04, 0.05, 0.06, -0.05, 0.05, 0.04])
SIM_DT = 0.001
RATE = 200.0  # joint_states and control per second: each tick integrates 5 steps of SIM_DT
STEPS_PER_TICK = 5
HOLD_S = 5.0


@pytest.fixture(scope="module")
def sim(module_nodes, ros):
    """The default arm in simulate mode (semi-implicit Euler at 1 ms, 200 ticks/s, commands
    never time out); it serves ~/linearize like a serve-mode node."""
    node = module_nodes.start(
        "-p", "mode:=simulate", "-p", "integrator:=semi_implicit_euler", "-p", f"sim_dt:={SIM_DT}",
        "-p", f"publish_rate:={RATE}", "-p", "command_timeout:=0.0", label="simulate",
    )
    ros.wait_for_service(Linearize, LIN)
    ros.call(SetBool, f"{NODE}/pause", SetBool.Request(data=True))
    return node


def request(names, q, v=(), effort=(), dt=0.0, **base):
    return Linearize.Request(name=list(names), position=[float(x) for x in q], velocity=[float(x) for x in v],
                             effort=[float(x) for x in effort], dt=float(dt), **base)


def matrices(r):
    """A (2n x 2n), B (2n x n) and the derivatives (n x n) of a response."""
    n = len(r.columns)
    assert r.success, r.message
    return (np.reshape(r.a, (2 * n, 2 * n)), np.reshape(r.b, (2 * n, n)), np.reshape(r.ddq_dq, (n, n)),
            np.reshape(r.ddq_dv, (n, n)), np.reshape(r.minv, (n, n)))


def pin_derivatives(ref, q, v, tau):
    pin.computeABADerivatives(ref.model, ref.data, q, v, tau)
    minv = np.array(ref.data.Minv)
    minv = np.triu(minv) + np.triu(minv, 1).T
    return np.array(ref.data.ddq_dq), np.array(ref.data.ddq_dv), minv


def semi_implicit_map(fq, fv, minv, h, dq=None, dv=None):
    """A, B of one semi-implicit Euler step of h from the derivatives of qdd (Dq = Dv = I for a
    fixed base)."""
    n = fq.shape[0]
    eye = np.eye(n)
    dq = eye if dq is None else dq
    dv = eye if dv is None else dv
    vel = np.hstack([h * fq, eye + h * fv])
    top = h * dv @ vel + np.hstack([dq, np.zeros((n, n))])
    return np.vstack([top, vel]), np.vstack([h * h * dv @ minv, h * minv])


def test_default_arm_against_pinocchio(ros, sim, ref):
    """Continuous and discrete maps, in the request's joint order, at a moving state with given
    efforts; with no efforts the point is tau = ID(q, v, 0)."""
    rng = np.random.default_rng(5)
    names = ARM_JOINTS[::-1]
    q_list = sd.random_positions(names, rng, sd.DEFAULT_ARM_URDF)
    v_list = rng.uniform(-1, 1, 7)
    tau_list = rng.uniform(-3, 3, 7)
    q, v, tau = ref.q(names, q_list), ref.v(names, v_list), ref.v(names, tau_list)
    fq, fv, minv = (ref.matrix(m, names) for m in pin_derivatives(ref, q, v, tau))
    qdd = ref.pick(ref.aba(q, v, tau), names)

    r = ros.call(Linearize, LIN, request(names, q_list, v_list, tau_list, dt=0.0))
    a, b, dq, dv, mi = matrices(r)
    assert list(r.columns) == names and r.dt == 0.0
    for got, want in [(dq, fq), (dv, fv), (mi, minv), (np.array(r.acceleration), qdd), (np.array(r.effort), tau_list)]:
        sd.assert_close(got, want, tol=TOL)
    n = 7
    want_a = np.block([[np.zeros((n, n)), np.eye(n)], [fq, fv]])
    sd.assert_close(a, want_a, "continuous A", tol=TOL)
    sd.assert_close(b, np.vstack([np.zeros((n, n)), minv]), "continuous B", tol=TOL)

    h = 0.004
    r = ros.call(Linearize, LIN, request(names, q_list, v_list, tau_list, dt=h))
    a, b, *_ = matrices(r)
    want_a, want_b = semi_implicit_map(fq, fv, minv, h)
    sd.assert_close(a, want_a, "discrete A", tol=TOL)
    sd.assert_close(b, want_b, "discrete B", tol=TOL)

    # No efforts: the point is tau = ID(q, v, 0), so qdd = 0 there.
    r = ros.call(Linearize, LIN, request(names, q_list, v_list, dt=0.0))
    assert r.success, r.message
    sd.assert_close(np.array(r.effort), ref.pick(ref.rnea(q, v, np.zeros(7)), names), "hold-still effort", tol=TOL)
    assert np.abs(r.acceleration).max() < 1e-9, r.acceleration


def pose_msg(p):
    return Pose(position=Point(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(x=p[3], y=p[4], z=p[5], w=p[6]))


def test_floating_base_against_pinocchio(module_nodes, ros):
    """The default arm on a floating base, turning: the corner -ad(v) (pin.Motion(v).action), the
    lower rows from computeABADerivatives, and one step's map from pin.dIntegrate."""
    module_nodes.start("-r", "__ns:=/floating", "-p", "floating_base:=true", label="floating")
    ref = sd.PinRef(sd.DEFAULT_ARM_URDF, floating=True)
    rng = np.random.default_rng(7)
    names = ARM_JOINTS
    q_list = sd.random_positions(names, rng, sd.DEFAULT_ARM_URDF)
    quat = rng.normal(size=4)
    pose = np.concatenate([[0.3, -0.2, 1.1], quat / np.linalg.norm(quat)])
    base6 = np.array([0.4, -0.3, 0.2, 1.5, -1.0, 2.0])
    v_list = rng.uniform(-1, 1, 7)
    tau_list = rng.uniform(-3, 3, 7)
    q = ref.q(names, q_list, base_pose=pose)
    v = ref.v(names, v_list, base6)
    tau = ref.v(names, tau_list, np.zeros(6))
    fq, fv, minv = (ref.matrix(m, names) for m in pin_derivatives(ref, q, v, tau))
    base = dict(base_pose=pose_msg(pose), base_twist=Twist(linear=Vector3(x=base6[0], y=base6[1], z=base6[2]),
                                                           angular=Vector3(x=base6[3], y=base6[4], z=base6[5])),
                base_wrench=Wrench())
    ros.wait_for_service(Linearize, FLOATING)
    r = ros.call(Linearize, FLOATING, request(names, q_list, v_list, tau_list, dt=0.0, **base))
    a, b, dq, dv, mi = matrices(r)
    n = 13
    suffixes = ["linear_x", "linear_y", "linear_z", "angular_x", "angular_y", "angular_z"]
    assert [c.split("/")[-1] for c in r.columns[:6]] == suffixes, r.columns
    assert list(r.columns)[6:] == names
    corner = np.zeros((n, n))
    corner[:6, :6] = -pin.Motion(base6[:3], base6[3:]).action
    want_a = np.block([[corner, np.eye(n)], [fq, fv]])
    sd.assert_close(a, want_a, "continuous A", tol=TOL)
    sd.assert_close(b, np.vstack([np.zeros((n, n)), minv]), "continuous B", tol=TOL)

    h = 0.02
    r = ros.call(Linearize, FLOATING, request(names, q_list, v_list, tau_list, dt=h, **base))
    a, b, *_ = matrices(r)
    qdd = ref.aba(q, v, tau)
    step = h * (v + h * qdd)
    order = list(range(ref.base.idx_v, ref.base.idx_v + 6)) + [ref.joints[j].idx_v for j in names]
    pick = np.ix_(order, order)
    dq_int = np.array(pin.dIntegrate(ref.model, q, step, pin.ArgumentPosition.ARG0))[pick]
    dv_int = np.array(pin.dIntegrate(ref.model, q, step, pin.ArgumentPosition.ARG1))[pick]
    want_a, want_b = semi_implicit_map(fq, fv, minv, h, dq_int, dv_int)
    sd.assert_close(a, want_a, "discrete A", tol=TOL)
    sd.assert_close(b, want_b, "discrete B", tol=TOL)


@pytest.mark.parametrize(
    "req, words",
    [
        (request(["joint1", "elbow", *ARM_JOINTS[2:]], np.zeros(7)), ["elbow"]),
        (request(ARM_JOINTS, [0, 0, float("nan"), 0, 0, 0, 0]), ["joint3"]),
        (request(ARM_JOINTS, np.zeros(7), dt=-0.001), ["dt", "-0.001"]),
        (request(ARM_JOINTS, np.zeros(7), dt=float("nan")), ["dt", "NaN"]),
        (request(ARM_JOINTS, np.zeros(6)), ["position", "6"]),
        (request(ARM_JOINTS, np.zeros(7), v=np.zeros(8)), ["velocity", "8"]),
        (request(ARM_JOINTS, np.zeros(7), effort=np.zeros(3)), ["effort", "3"]),
        (request(ARM_JOINTS, np.zeros(7), effort=[0, 0, 0, float("inf"), 0, 0, 0]), ["effort", "joint4"]),
        (request(ARM_JOINTS, np.zeros(7), v=[1e300] * 7), ["finite"]),
    ],
    ids=["unknown joint", "NaN position", "negative dt", "NaN dt", "short position", "long velocity",
         "short effort", "infinite effort", "overflowing state"],
)
def test_bad_requests_are_refused(ros, sim, req, words):
    r = ros.call(Linearize, LIN, req)
    assert not r.success and r.message
    for w in words:
        assert w in r.message, r.message
    assert not (r.columns or r.a or r.b or r.ddq_dq or r.ddq_dv or r.minv or r.effort or r.acceleration)
    # The node still answers.
    assert ros.call(Linearize, LIN, request(ARM_JOINTS, Q0)).success


# -- the controller ------------------------------------------------------------------------------


def dlqr(a, b, q, r):
    """The infinite-horizon discrete LQR gain, by iterating the Riccati difference equation
    P <- Q + A'P(A - BK), K = (R + B'PB)^-1 B'PA, until P stops changing (relative 1e-14)."""
    p = q.copy()
    for _ in range(100_000):
        k = np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)
        nxt = q + a.T @ p @ (a - b @ k)
        if np.abs(nxt - p).max() <= 1e-14 * np.abs(nxt).max():
            return k
        p = nxt
    raise AssertionError("the Riccati iteration did not converge")


def tick_map(a1, b1):
    """One tick (STEPS_PER_TICK steps with the effort held) about an equilibrium: A1^m and
    sum_k A1^k B1; exact to first order because the steps all start from the same point."""
    a, b = np.eye(a1.shape[0]), np.zeros_like(b1)
    for _ in range(STEPS_PER_TICK):
        a, b = a1 @ a, a1 @ b + b1
    return a, b


def weights(minv):
    """Q on angle errors (1 per rad^2) and a little on rates; R = 1e-3 M^-2, i.e. a cost on the
    accelerations the efforts give, so every joint, light wrist or heavy shoulder, gets about the
    same bandwidth (closed-loop rates 4-14 1/s at Q0, stable with up to 6 ticks = 30 ms of
    delay: checked in the test)."""
    n = minv.shape[0]
    return np.diag([1.0] * n + [0.01] * n), 1e-3 * minv @ minv


def delayed_spectral_radius(a, b, k, ticks):
    """Spectral radius of x+ = A x - B K x(-ticks): the loop with that many ticks of delay."""
    n = a.shape[0]
    big = np.zeros((n * (ticks + 1), n * (ticks + 1)))
    big[:n, :n] = a
    big[:n, n * ticks:n * (ticks + 1)] -= b @ k
    for i in range(ticks):
        big[n * (i + 1):n * (i + 2), n * i:n * (i + 1)] = np.eye(n)
    return np.abs(np.linalg.eigvals(big)).max()


def fd_derivatives(ros, eps=1e-5):
    """d(qdd)/dq, d(qdd)/dv, d(qdd)/dtau at (Q0, 0, g(Q0)) by central differences of
    ~/forward_dynamics (2 * 21 calls)."""
    g = np.array(ros.call(InverseDynamics, f"{NODE}/inverse_dynamics",
                          InverseDynamics.Request(name=ARM_JOINTS, position=list(Q0))).effort)

    def qdd(q, v, tau):
        r = ros.call(ForwardDynamics, f"{NODE}/forward_dynamics",
                     ForwardDynamics.Request(name=ARM_JOINTS, position=list(q), velocity=list(v), effort=list(tau)))
        assert r.success, r.message
        return np.array(r.acceleration)

    base = [Q0, np.zeros(7), g]
    cols = [[], [], []]
    for which in range(3):
        for k in range(7):
            plus, minus = [x.copy() for x in base], [x.copy() for x in base]
            plus[which][k] += eps
            minus[which][k] -= eps
            cols[which].append((qdd(*plus) - qdd(*minus)) / (2 * eps))
    return [np.array(c).T for c in cols]


def test_lqr_from_linearize_holds_the_arm_and_matches_finite_differences(ros, sim):
    # u0 = g(q0) from ~/inverse_dynamics; the service's hold-still effort is the same.
    g = np.array(ros.call(InverseDynamics, f"{NODE}/inverse_dynamics",
                          InverseDynamics.Request(name=ARM_JOINTS, position=list(Q0))).effort)
    assert np.abs(g).max() > 5.0, "the pose must be away from the gravity equilibrium"
    r = ros.call(Linearize, LIN, request(ARM_JOINTS, Q0, dt=SIM_DT))
    a1, b1, _, _, minv = matrices(r)
    sd.assert_close(np.array(r.effort), g, "u0", tol=1e-12)
    a, b = tick_map(a1, b1)
    q_w, r_w = weights(minv)
    k = dlqr(a, b, q_w, r_w)
    for ticks in range(7):
        rho = delayed_spectral_radius(a, b, k, ticks)
        assert rho < 0.99, f"the design is not robust to {ticks} ticks of delay: spectral radius {rho}"

    # The same design from central differences of ~/forward_dynamics: the gains agree. Each
    # derivative's error is that of a central difference, eps^2 |qdd'''| / 6 + eps_mach |qdd| / eps,
    # about 1e-9 relative to the derivatives at eps = 1e-5; the Riccati solution is smooth in A, B,
    # so the gains may differ by that times its conditioning: 1e-6 of the gain's size is the bound
    # (measured about 1e-9).
    fq, fv, fu = fd_derivatives(ros)
    a1_fd, b1_fd = semi_implicit_map(fq, fv, fu, SIM_DT)
    k_fd = dlqr(*tick_map(a1_fd, b1_fd), q_w, r_w)
    gap = np.abs(k_fd - k).max() / np.abs(k).max()
    print(f"LQR gain from finite differences vs ~/linearize: {gap:.1e} of max |K| = {np.abs(k).max():.1f}")
    assert gap < 1e-6, gap

    # Hold the arm: u = g(q0) + K (x0 - x) on every joint_states, from a perturbed start.
    commands = ros.publisher(Float64MultiArray, f"{NODE}/commands")
    samples = []

    def control(msg):
        order = [list(msg.name).index(j) for j in ARM_JOINTS]
        q = np.array(msg.position)[order]
        v = np.array(msg.velocity)[order]
        u = g - k @ np.concatenate([q - Q0, v])
        commands.publish(Float64MultiArray(data=[float(x) for x in u]))
        samples.append((msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec, q))

    reset = ros.call(Reset, f"{NODE}/reset", Reset.Request(name=ARM_JOINTS, position=list(START), velocity=[]))
    assert reset.success, reset.message
    sub = ros.node.create_subscription(JointState, "/joint_states", control, sd.qos_reliable(depth=10))
    try:
        assert ros.call(SetBool, f"{NODE}/pause", SetBool.Request(data=False)).success
        assert ros.spin_until(lambda: len(samples) > 0, sd.EVENT_S), "no joint_states"
        t0 = samples[0][0]
        assert ros.spin_until(lambda: samples[-1][0] - t0 >= HOLD_S, 10 * HOLD_S), "the simulation did not run 5 s"
    finally:
        ros.call(SetBool, f"{NODE}/pause", SetBool.Request(data=True))
        ros.node.destroy_subscription(sub)
    first = np.abs(samples[0][1] - Q0).max()
    last = [np.abs(q - Q0).max() for t, q in samples if t - t0 >= HOLD_S - 0.1]
    print(f"LQR hold: error {first * 1e3:.1f} mrad at the start, {max(last) * 1e3:.2e} mrad over the last 0.1 s")
    assert first > 0.03, "the arm did not start away from q0"
    assert max(last) < 1e-3, f"not held within 1 mrad after {HOLD_S} s: {max(last)} rad"
