"""Reference test: our ``spatial_dynamics`` binary against Pinocchio on real robot models.

Pinocchio (PyPI ``pin``) is an independent implementation of the same rigid-body algorithms;
the robots come from PyPI ``example-robot-data`` (URDF only: models are built with
``pin.buildModelFromUrdf``, meshes are never loaded). For every case we start ONE
``spatial_dynamics eval`` process, stream ``N_STATES`` random states through it (inverse
dynamics, forward dynamics by each of ``aba``/``crba``/``rnea_columns``, mass matrix, gravity)
and compare each answer with Pinocchio::

    ||ours - ref|| <= REL_TOL * max(1, ||ref||)      (2-norm; Frobenius for M)

Mapping conventions (the two programs do not number coordinates the same way):

* Joints are matched by NAME between our ``model --json`` and Pinocchio's ``model.names`` /
  ``model.joints[j].idx_q, idx_v, nq, nv``; from that we build index maps for q and v. Nothing
  assumes the same joint order (ours may be e.g. depth-first in URDF child order).
  A velocity-space vector maps by a permutation ``p`` with ``x_ours = x_pin[p]``, the mass
  matrix by ``M_ours = M_pin[p][:, p]``.
* The floating base is matched by TYPE, not name: our joint of type ``floating`` <-> Pinocchio's
  ``JointModelFreeFlyer``. Both use q = [x y z qx qy qz qw] (position in world, unit quaternion
  x,y,z,w) and v = [linear; angular] twist in the base frame, so its block is copied as is, only
  located by index. Floating-base cases build ``pin.buildModelFromUrdf(path,
  pin.JointModelFreeFlyer())`` and run ours with ``--floating-base``.
* Continuous joints: Pinocchio (``JointModelRUBX``... , nq=2, nv=1) stores (cos t, sin t); ours
  stores the single angle t = atan2(sin, cos). v, a, tau are the same scalar.
* Revolute and prismatic joints: one coordinate, copied.
* Planar joints are not mapped (none of these robots has one; Pinocchio's planar q/v convention
  is its own) - a planar joint is reported as a layout error.
* Mimic joints. Pinocchio ignores ``<mimic>`` by default, so the plain cases run ours with
  ``--ignore-mimic`` (a mimic joint is then an ordinary joint in both). The ``*_mimic`` cases run
  ours with mimic honoured (our default): the mimic joint has no coordinate of its own and the
  dynamics are those of the constrained system, q_mimic = multiplier * q_primary + offset.
  Their reference is either
    - ``native``: ``pin.buildModelFromUrdf(path, mimic=True)`` (``JointModelMimic``, nq=nv=0).
      ``pin.aba`` refuses mimic joints, so forward dynamics there is solve(crba, tau - nle);
    - ``projected``: Pinocchio's mimic-ignored model seen through the mimic map G
      (v_full = G v, a_full = G a since G is constant): tau = G^T rnea(q_full, G v, G a),
      M = G^T M_full G, g = G^T g_full, a = solve(M, tau - G^T nle(q_full, G v)).
      Used for TALOS, which pin 4.1 refuses to build with mimic=True ("The parent joint of the
      mimic joint is not in the kinematic tree": its gripper mimic joints precede their primary
      joint in the tree). The self-check below verifies projected == native on Panda and Baxter.
  If the installed pin has no ``mimic=`` argument or cannot build a ``native`` case, that case is
  skipped with the reason. Our ``aba`` answers an error for honoured mimic joints (as pin.aba
  does); that refusal is reported as a skip of ``*_mimic-forward_dynamics_aba`` (see
  MIMIC_ABA_REFUSAL_OK); ``crba`` and ``rnea_columns`` are compared.
* Mass matrix: ``pin.crba`` is symmetrised from its upper triangle (pin 4.1's binding already
  returns the full matrix; older ones filled only the upper triangle).

Robots with ``<mimic>`` tags: Panda (1: finger_joint2 <- finger_joint1), Baxter (2 gripper
fingers, multiplier -1), TALOS full v2 (12 gripper joints <- gripper_{left,right}_joint).
UR5, Solo12, ANYmal and Kinova have none. Of these robots only Kinova (an extra case added for
exactly this reason) has continuous joints (3), so it is what exercises the (cos, sin) mapping.

Random states (seeded numpy RNG, per-case seed): revolute/prismatic uniform within the URDF
limits (+-pi / +-1 if a limit is infinite), continuous angles uniform in [-pi, pi], floating base
position uniform in [-1, 1]^3 and a uniform random unit quaternion; v, a, tau standard normal.
This is what pin.randomConfiguration does, but reproducible from our own RNG.

Forward-dynamics conditioning: with pin 4.1, cond(M) over the sampled states is at most about
3e2 (UR5), 1e3 (Panda, Baxter), 1.2e6 (TALOS), 3e4 (Solo12), 4e3 (ANYmal), 2e4 (Kinova), and
Pinocchio's own aba vs solve(crba) differ by < 1e-14 relative, so REL_TOL = 1e-9 is kept for
forward dynamics too (cond(M) * eps < 3e-10 even for TALOS) - no cond(M) scaling. Failure
messages for forward dynamics print cond(M) so that a conditioning problem can be told from a
bug.

The binary: ``$SPATIAL_DYNAMICS_BIN`` or ``<repo>/target/release/spatial_dynamics``. A missing
binary FAILS the tests (this is a required reference test).

Standalone use (no binary needed)::

    python tests/python/test_pinocchio_reference.py --self-check

runs every case against a fake binary built from Pinocchio itself (this same file run as
``--fake-binary model|eval ...``, with its own, independently written, conversion code and a
shuffled joint order), checks that the pin q -> our q -> pin q round trip gives identical
numbers, that the projected mimic reference equals Pinocchio's native mimic model, and that
deliberately wrong fakes (FAKE_SABOTAGE=order|continuous|quaternion_wxyz|mimic) are caught.
``--report`` prints the worst relative error per case and quantity for the real binary;
``--describe`` prints what Pinocchio sees in each robot.
"""

from __future__ import annotations

import json
import math
import os
import sys
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pinocchio_cases import (  # noqa: E402, F401  (shared with the other reference tests)
    _ANYMAL,
    _BAXTER,
    binary_path,
    build_pin_model,
    build_reference,
    cached,
    Case,
    CaseSkip,
    DEFAULT_BIN,
    EVAL_TIMEOUT_S,
    format_command,
    _KINOVA,
    LayoutError,
    Mapping,
    NativeRef,
    _PANDA,
    ProjectedMimicRef,
    _QUARTER_TURNS,
    RefJoint,
    REPO,
    require_binary,
    run_eval,
    robots_dir,
    run_command,
    sample_state,
    _SOLO12,
    _TALOS,
    _UR5,
    _urdf_mimics,
    urdf_path,
)

try:  # pytest is only needed for the test run, not for --self-check / --fake-binary
    import pytest
except ImportError:  # pragma: no cover
    pytest = None

# ----------------------------------------------------------------------------------------------
# Constants
# ----------------------------------------------------------------------------------------------

REL_TOL = 1e-9  # ||ours - ref|| <= REL_TOL * max(1, ||ref||), every quantity, every state
N_STATES = 20  # random states per case
SEED = 20240611  # base seed; each case mixes in a CRC of its name
# Our eval answers forward_dynamics method "aba" with an error when a joint mimics another
# (mimic honoured), exactly as pin.aba does ("does not support Joint Mimic"); that refusal is
# the documented contract, so it passes when it names "mimic" and covers every state (anything
# less fails). Numbers, if given instead, are compared like any other.
MIMIC_ABA_REFUSAL_OK = True


FD_METHODS = ("aba", "crba", "rnea_columns")
QUANTITIES = (
    "layout",
    "inverse_dynamics",
    "forward_dynamics_aba",
    "forward_dynamics_crba",
    "forward_dynamics_rnea_columns",
    "mass_matrix",
    "gravity",
)


CASES = (
    Case("ur5", _UR5),
    Case("panda", _PANDA),
    Case("baxter", _BAXTER),
    Case("talos", _TALOS),
    Case("solo12", _SOLO12, floating=True),
    Case("anymal", _ANYMAL, floating=True),
    Case("kinova", _KINOVA),  # extra: the only one with continuous joints
    Case("quarter_turns", _QUARTER_TURNS),
    Case("quarter_turns_floating", _QUARTER_TURNS, floating=True),
    Case("panda_mimic", _PANDA, mimic="native"),
    Case("baxter_mimic", _BAXTER, mimic="native"),
    Case("talos_mimic", _TALOS, mimic="projected"),
)


# Reductions (issue 5): a TALOS leg from the fixed pelvis to the sole, and an arm from the upper
# torso to the wrist (the gripper lumps onto the wrist, the rest of the robot is fixed).
REDUCED_CASES = (
    Case("talos_right_leg", _TALOS, reduce=("--tip", "leg_right_6_link"), keep="leg_right_"),
    Case("talos_left_arm", _TALOS, reduce=("--root", "torso_2_link", "--tip", "arm_left_7_link"), keep="arm_left_"),
)


# ----------------------------------------------------------------------------------------------
# Running one case
# ----------------------------------------------------------------------------------------------


@dataclass
class CaseResult:
    path: Path = None
    ref_label: str = ""
    skip: str = ""  # reason: reference not buildable with this pin
    layout_error: str = ""
    error: str = ""  # running the binary failed
    # quantity -> list of (state index, err norm, max abs err, ref norm, bound, note)
    records: dict = field(default_factory=dict)
    bad_answers: dict = field(default_factory=dict)  # quantity -> [(state, message)]


def compute_case(case: Case, command: list) -> CaseResult:
    """Everything for one case: one `model --json` run and ONE `eval` run with all requests."""
    res = CaseResult()
    res.path = urdf_path(case)
    try:
        ref = build_reference(case, res.path)
    except CaseSkip as exc:
        res.skip = str(exc)
        return res
    res.ref_label = ref.label
    flags = ["--urdf", str(res.path), *case.our_flags()]

    cmd = [*command, "model", *flags, "--json"]
    out = run_command(cmd)
    if out.returncode != 0:
        res.error = f"`{format_command(cmd)}` exited {out.returncode}: {out.stderr.strip()[:2000]}"
        return res
    try:
        ours = json.loads(out.stdout)
    except json.JSONDecodeError as exc:
        res.error = f"`{format_command(cmd)}` printed no JSON ({exc}): {out.stdout[:500]!r}"
        return res
    try:
        mapping = Mapping.build(ours, ref)
    except LayoutError as exc:
        res.layout_error = str(exc)
        return res

    rng = np.random.default_rng(SEED ^ zlib.crc32(case.name.encode()))
    states, lines, slots = [], [], []  # slots[k] = (state index, quantity) of request k
    for i in range(N_STATES):
        q, v, a, tau = sample_state(ref, rng)
        q_ours = mapping.q_to_ours(q)
        q = mapping.q_to_ref(q_ours)  # what we send, exactly, back in Pinocchio's convention
        states.append((q, v, a, tau))
        qo, vo, ao, to = q_ours.tolist(), *(mapping.v_to_ours(x).tolist() for x in (v, a, tau))
        lines.append({"op": "inverse_dynamics", "q": qo, "v": vo, "a": ao})
        slots.append((i, "inverse_dynamics"))
        for method in FD_METHODS:
            lines.append({"op": "forward_dynamics", "q": qo, "v": vo, "tau": to, "method": method})
            slots.append((i, f"forward_dynamics_{method}"))
        lines.append({"op": "mass_matrix", "q": qo})
        slots.append((i, "mass_matrix"))
        lines.append({"op": "gravity", "q": qo})
        slots.append((i, "gravity"))

    answers, res.error = run_eval(command, flags, lines)
    if res.error:
        return res

    cache = {}  # (state, what) -> reference value, so M is computed once per state
    for (i, quantity), line in zip(slots, answers):
        q, v, a, tau = states[i]
        try:
            ans = json.loads(line)
        except json.JSONDecodeError:
            res.bad_answers.setdefault(quantity, []).append((i, f"not JSON: {line[:300]!r}"))
            continue
        if "error" in ans:
            res.bad_answers.setdefault(quantity, []).append((i, f"error answer: {ans['error']}"))
            continue
        note = ""
        try:
            if quantity == "mass_matrix":
                got = np.array(ans["M"], dtype=float)
                if got.shape != (ref.nv, ref.nv):
                    raise ValueError(f"M has shape {got.shape}, expected {(ref.nv, ref.nv)}")
                got = mapping.m_to_ref(got)
                want = cache.setdefault((i, "M"), ref.mass_matrix(q))
            else:
                key = "a" if quantity.startswith("forward_dynamics") else "tau"
                got = np.array(ans[key], dtype=float)
                if got.shape != (ref.nv,):
                    raise ValueError(f"{key} has shape {got.shape}, expected {(ref.nv,)}")
                got = mapping.v_to_ref(got)
                if quantity == "inverse_dynamics":
                    want = ref.rnea(q, v, a)
                elif quantity == "gravity":
                    want = ref.gravity(q)
                else:
                    want = cache.get((i, "fd"))
                    if want is None:
                        want = cache[(i, "fd")] = ref.forward_dynamics(q, v, tau)
                    mm = cache.setdefault((i, "M"), ref.mass_matrix(q))
                    note = f"cond(M)={np.linalg.cond(mm):.2e}"
        except (KeyError, TypeError, ValueError) as exc:
            res.bad_answers.setdefault(quantity, []).append((i, f"malformed answer ({exc!r}): {line[:300]}"))
            continue
        err = float(np.linalg.norm(got - want))
        if not math.isfinite(err):
            err = math.inf
        max_abs = float(np.max(np.abs(got - want))) if got.size else 0.0
        ref_norm = float(np.linalg.norm(want))
        res.records.setdefault(quantity, []).append(
            (i, err, max_abs, ref_norm, REL_TOL * max(1.0, ref_norm), note)
        )
    return res


_RESULTS: dict = {}


def res_of(case: Case) -> CaseResult:
    return case_result(case)


def case_result(case: Case, command=None) -> CaseResult:
    return cached(_RESULTS, compute_case, case, command)


def check(case: Case, quantity: str, res: CaseResult):
    """(verdict, message): verdict "ok", "fail" or "skip" (see MIMIC_ABA_REFUSAL_OK)."""
    where = f"{case.name} ({res.path.name}, flags {' '.join(case.our_flags()) or 'none'}; ref {res.ref_label})"
    if res.skip:
        return "skip", f"{case.name}: {res.skip}"
    if res.error:
        return "fail", f"{where}: {res.error}"
    if res.layout_error:
        return "fail", f"{where}: layout mismatch between our `model --json` and pinocchio: {res.layout_error}"
    if quantity == "layout":
        return "ok", ""
    msgs = []
    bad = res.bad_answers.get(quantity, [])
    if (
        MIMIC_ABA_REFUSAL_OK
        and case.mimic
        and quantity == "forward_dynamics_aba"
        and len(bad) == N_STATES
        and all(text.startswith("error answer:") and "mimic" in text for _, text in bad)
    ):
        # The contract: aba refuses mimic models with an error naming the mimic joint.
        return "ok", ""
    for i, text in bad[:5]:
        msgs.append(f"state {i}: {text}")
    recs = res.records.get(quantity, [])
    if len(recs) + len(bad) != N_STATES:
        msgs.append(f"{len(recs) + len(bad)} answers for {N_STATES} states")
    failing = [r for r in recs if not (r[1] <= r[4])]
    if failing:
        worst = max(failing, key=lambda r: r[1] / r[4])
        msgs.append(
            f"{len(failing)}/{len(recs)} states exceed the tolerance "
            f"(||ours-ref|| <= {REL_TOL:g}*max(1,||ref||)); states {[r[0] for r in failing]}; worst: "
            f"state {worst[0]}: ||err||={worst[1]:.3e}, max |err|={worst[2]:.3e}, "
            f"||ref||={worst[3]:.3e}, bound={worst[4]:.3e} {worst[5]}".rstrip()
        )
    if msgs:
        return "fail", f"{where} {quantity}: " + "; ".join(msgs)
    return "ok", ""


# ----------------------------------------------------------------------------------------------
# pytest
# ----------------------------------------------------------------------------------------------

if pytest is not None:

    def test_binary_exists():
        path = binary_path()
        if not (path.is_file() and os.access(path, os.X_OK)):
            pytest.fail(
                f"spatial_dynamics binary not found or not executable at {path} "
                "(build it with `cargo build --release` or set SPATIAL_DYNAMICS_BIN)"
            )

    @pytest.mark.parametrize("quantity", QUANTITIES)
    @pytest.mark.parametrize("case", CASES + REDUCED_CASES, ids=[c.name for c in CASES + REDUCED_CASES])
    def test_against_pinocchio(case, quantity):
        require_binary()
        verdict, msg = check(case, quantity, res_of(case))
        if verdict == "skip":
            pytest.skip(msg)
        if verdict == "fail":
            pytest.fail(msg, pytrace=False)


# ----------------------------------------------------------------------------------------------
# Self-check: a fake binary made of Pinocchio, and round trips
# ----------------------------------------------------------------------------------------------


def _fake_parse(argv):
    opts = {"urdf": None, "floating": False, "ignore_mimic": False, "json": False, "gravity": None}
    it = iter(argv)
    for arg in it:
        if arg == "--urdf":
            opts["urdf"] = next(it)
        elif arg == "--floating-base":
            opts["floating"] = True
        elif arg == "--ignore-mimic":
            opts["ignore_mimic"] = True
        elif arg == "--json":
            opts["json"] = True
        elif arg == "--gravity":
            opts["gravity"] = [float(x) for x in next(it).split(",")]
        else:
            raise SystemExit(f"fake binary: unknown argument {arg}")
    return opts


class _FakeBinary:
    """Our binary's CLI, emulated with Pinocchio. Its conversion code is written independently
    of Mapping (explicit per-joint loops), and its joint order is a shuffle of Pinocchio's,
    so that the self-check exercises the name matching and a nontrivial permutation."""

    def __init__(self, opts):
        path = Path(opts["urdf"])
        if opts["ignore_mimic"]:
            self.ref = NativeRef(build_pin_model(path, opts["floating"]), "fake")
        else:  # honoured mimic: any robot, through the projection
            self.ref = ProjectedMimicRef(path, opts["floating"])
        models = [self.ref.model] if hasattr(self.ref, "model") else [self.ref.full.model]
        if opts["gravity"] is not None:
            for m in models:
                m.gravity.linear = np.array(opts["gravity"])
        order = np.random.default_rng(zlib.crc32(str(path).encode())).permutation(len(self.ref.joints))
        self.joints = []  # (ref joint, our q_index, our nq, our v_index)
        qi = vi = 0
        for k in order:
            rj = self.ref.joints[k]
            nq = 1 if rj.kind == "continuous" else rj.nq
            self.joints.append((rj, qi, nq, vi))
            qi, vi = qi + nq, vi + rj.nv
        self.nq, self.nv = qi, vi
        # Negative controls for the self-check: deliberately wrong fakes that must be caught.
        self.sabotage = os.environ.get("FAKE_SABOTAGE", "")
        if self.sabotage == "order":  # advertise the shuffled order, compute in Pinocchio's
            self.model_joints = self.joints
            self.joints = []
            qi = vi = 0
            for rj in self.ref.joints:
                nq = 1 if rj.kind == "continuous" else rj.nq
                self.joints.append((rj, qi, nq, vi))
                qi, vi = qi + nq, vi + rj.nv
        if self.sabotage == "mimic" and isinstance(self.ref, ProjectedMimicRef):  # wrong sign
            for row_q, row_v in self.ref.mimic_rows:
                self.ref.Sq[row_q] *= -1
                self.ref.G[row_v] *= -1

    def model_json(self):
        return {
            "nq": self.nq,
            "nv": self.nv,
            "joints": [
                {
                    "name": "root_joint" if rj.kind == "floating" else rj.name,
                    "type": rj.kind,
                    "q_index": qi,
                    "nq": nq,
                    "v_index": vi,
                    "nv": rj.nv,
                }
                for rj, qi, nq, vi in getattr(self, "model_joints", self.joints)
            ],
        }

    def q_in(self, q):
        out = np.zeros(self.ref.nq)
        for rj, qi, nq, _ in self.joints:
            for k in range(rj.nq):
                if rj.kind == "continuous":
                    t = -q[qi] if self.sabotage == "continuous" else q[qi]
                    out[rj.idx_q + k] = math.cos(t) if k == 0 else math.sin(t)
                else:
                    out[rj.idx_q + k] = q[qi + k]
            if rj.kind == "floating" and self.sabotage == "quaternion_wxyz":
                out[rj.idx_q + 3 : rj.idx_q + 7] = np.roll(out[rj.idx_q + 3 : rj.idx_q + 7], -1)
        return out

    def v_in(self, x):
        out = np.zeros(self.ref.nv)
        for rj, _, _, vi in self.joints:
            for k in range(rj.nv):
                out[rj.idx_v + k] = x[vi + k]
        return out

    def v_out(self, x):
        out = [0.0] * self.nv
        for rj, _, _, vi in self.joints:
            for k in range(rj.nv):
                out[vi + k] = float(x[rj.idx_v + k])
        return out

    def m_out(self, m):
        out = [[0.0] * self.nv for _ in range(self.nv)]
        for rj, _, _, vi in self.joints:
            for rk, _, _, vk in self.joints:
                for a in range(rj.nv):
                    for b in range(rk.nv):
                        out[vi + a][vk + b] = float(m[rj.idx_v + a, rk.idx_v + b])
        return out

    def answer(self, req):
        q = self.q_in(req["q"])
        op = req["op"]
        if op == "inverse_dynamics":
            return {"tau": self.v_out(self.ref.rnea(q, self.v_in(req["v"]), self.v_in(req["a"])))}
        if op == "forward_dynamics":
            if req.get("method") not in FD_METHODS:
                return {"error": f"unknown forward-dynamics method {req.get('method')!r}"}
            return {"a": self.v_out(self.ref.forward_dynamics(q, self.v_in(req["v"]), self.v_in(req["tau"])))}
        if op == "mass_matrix":
            return {"M": self.m_out(self.ref.mass_matrix(q))}
        if op == "gravity":
            return {"tau": self.v_out(self.ref.gravity(q))}
        return {"error": f"unknown op {op!r}"}


def fake_binary_main(argv):
    sub, opts = argv[0], _fake_parse(argv[1:])
    fake = _FakeBinary(opts)
    if sub == "model":
        print(json.dumps(fake.model_json()))
        return 0
    if sub == "eval":
        for line in sys.stdin:
            try:
                ans = fake.answer(json.loads(line))
            except Exception as exc:  # like ours: answer an error and go on
                ans = {"error": f"bad request: {exc}"}
            sys.stdout.write(json.dumps(ans) + "\n")
        return 0
    raise SystemExit(f"fake binary: unknown subcommand {sub}")


def self_check() -> int:
    print(f"pinocchio {pin.__version__}, example-robot-data robots in {robots_dir()}")
    failures = 0
    fake_cmd = [sys.executable, str(Path(__file__).resolve()), "--fake-binary"]

    # 1. Round trips through the mapping (fake model JSON, shuffled order).
    print("\n[1] pin q -> our q -> pin q, and v/M permutations (Mapping vs the fake's own code)")
    for case in CASES:
        path = urdf_path(case)
        try:
            ref = build_reference(case, path)
        except CaseSkip as exc:
            print(f"  {case.name:14s} SKIP {exc}")
            continue
        fake = _FakeBinary({"urdf": str(path), "floating": case.floating, "ignore_mimic": not case.mimic, "gravity": None})
        mapping = Mapping.build(fake.model_json(), ref)
        rng = np.random.default_rng(1)
        worst_q = worst_v = 0.0
        nontrivial = bool(np.any(mapping.perm != np.arange(ref.nv)))
        for _ in range(N_STATES):
            q, v, _, _ = sample_state(ref, rng)
            qo = mapping.q_to_ours(q)
            back = mapping.q_to_ref(qo)
            worst_q = max(worst_q, float(np.max(np.abs(back - q))))
            # the fake's independent conversion must agree with Mapping's, bit for bit
            if not np.array_equal(fake.q_in(qo), back):
                print(f"  {case.name}: fake.q_in and Mapping.q_to_ref disagree")
                failures += 1
            if not np.array_equal(np.array(fake.v_out(v)), mapping.v_to_ours(v)):
                print(f"  {case.name}: fake.v_out and Mapping.v_to_ours disagree")
                failures += 1
            worst_v = max(worst_v, float(np.max(np.abs(mapping.v_to_ref(mapping.v_to_ours(v)) - v))))
            m = ref.mass_matrix(q)
            if not np.array_equal(mapping.m_to_ref(np.array(fake.m_out(m))), m):
                print(f"  {case.name}: M permutation round trip differs")
                failures += 1
            # dynamics at the round-tripped q are Pinocchio's dynamics at q
            d = np.max(np.abs(ref.rnea(back, v, v) - ref.rnea(q, v, v)))
            if d > 1e-12 * max(1.0, float(np.linalg.norm(ref.rnea(q, v, v)))):
                print(f"  {case.name}: rnea at round-tripped q differs by {d:.2e}")
                failures += 1
        ncont = sum(j.kind == "continuous" for j in ref.joints)
        print(
            f"  {case.name:14s} nq={ref.nq} nv={ref.nv} continuous={ncont} shuffled={nontrivial} "
            f"max|q round trip|={worst_q:.1e} max|v round trip|={worst_v:.1e}"
        )
        if worst_q > 4e-16 or worst_v != 0.0:
            failures += 1

    # 2. Projected mimic reference vs Pinocchio's native mimic model.
    print("\n[2] projected mimic reference vs pin.buildModelFromUrdf(mimic=True)")
    for case in (c for c in CASES if c.mimic):
        path = urdf_path(case)
        try:
            native = NativeRef(build_pin_model(path, case.floating, mimic=True), "native")
        except Exception as exc:
            print(f"  {case.name:14s} native mimic model unavailable: {exc}")
            continue
        proj = ProjectedMimicRef(path, case.floating)
        mapping = Mapping.build(
            {
                "nq": proj.nq,
                "nv": proj.nv,
                "joints": [
                    {"name": j.name, "type": j.kind, "q_index": j.idx_q, "nq": j.nq, "v_index": j.idx_v, "nv": j.nv}
                    for j in proj.joints
                ],
            },
            native,
        )
        rng = np.random.default_rng(2)
        worst = 0.0
        for _ in range(N_STATES):
            q, v, a, tau = sample_state(native, rng)
            qp, vp, ap, tp = mapping.q_to_ours(q), *(mapping.v_to_ours(x) for x in (v, a, tau))
            pairs = [
                (native.rnea(q, v, a), mapping.v_to_ref(proj.rnea(qp, vp, ap))),
                (native.gravity(q), mapping.v_to_ref(proj.gravity(qp))),
                (native.forward_dynamics(q, v, tau), mapping.v_to_ref(proj.forward_dynamics(qp, vp, tp))),
                (native.mass_matrix(q), mapping.m_to_ref(proj.mass_matrix(qp))),
            ]
            for want, got in pairs:
                worst = max(worst, float(np.linalg.norm(got - want)) / max(1.0, float(np.linalg.norm(want))))
        ok = worst <= REL_TOL
        failures += not ok
        print(f"  {case.name:14s} max relative difference {worst:.2e} {'ok' if ok else 'FAIL'}")

    # 3. The whole pipeline (subprocess, JSON, mapping, comparison) against the fake binary.
    print("\n[3] every case through compute_case() with the fake binary")
    failures += summarize(fake_cmd)

    # 4. Negative controls: deliberately wrong fakes must make the comparison fail.
    print("\n[4] negative controls: sabotaged fakes must be caught")
    controls = {
        "order": [c for c in CASES if c.name in ("ur5", "solo12", "kinova", "baxter_mimic")],
        "continuous": [c for c in CASES if c.name in ("kinova", "ur5")],
        "quaternion_wxyz": [c for c in CASES if c.name in ("solo12", "anymal", "ur5")],
        "mimic": [c for c in CASES if c.mimic or c.name == "panda"],
    }
    expect_caught = {
        "order": {"ur5", "solo12", "kinova", "baxter_mimic"},
        "continuous": {"kinova"},
        "quaternion_wxyz": {"solo12", "anymal"},
        "mimic": {"panda_mimic", "baxter_mimic", "talos_mimic"},
    }
    old_env = os.environ.get("FAKE_SABOTAGE")
    try:
        for mode, cases in controls.items():
            os.environ["FAKE_SABOTAGE"] = mode
            caught = set()
            for case in cases:
                res = compute_case(case, fake_cmd)  # not cached
                if res.skip:
                    continue
                if any(check(case, quantity, res)[0] == "fail" for quantity in QUANTITIES):
                    caught.add(case.name)
            ok = caught == expect_caught[mode]
            failures += not ok
            print(f"  {mode:16s} caught in {sorted(caught)} {'ok' if ok else f'FAIL (expected {sorted(expect_caught[mode])})'}")
    finally:
        if old_env is None:
            os.environ.pop("FAKE_SABOTAGE", None)
        else:
            os.environ["FAKE_SABOTAGE"] = old_env

    print(f"\nself-check: {'OK' if failures == 0 else f'{failures} FAILURE(S)'}")
    return 1 if failures else 0


def summarize(command) -> int:
    """Print the worst relative error per case and quantity; return the number of failures."""
    failures = 0
    for case in CASES:
        res = case_result(case, command)
        if res.skip:
            print(f"  {case.name:14s} SKIP {res.skip}")
            continue
        line = []
        for quantity in QUANTITIES:
            verdict, msg = check(case, quantity, res)
            short = quantity.replace("forward_dynamics", "fd")
            if verdict == "fail":
                failures += 1
                print(f"  FAIL {msg}")
            elif verdict == "skip":
                line.append(f"{short}=skipped")
            elif quantity != "layout":
                worst = max(r[1] / max(1.0, r[3]) for r in res.records[quantity])
                line.append(f"{short}={worst:.0e}")
        print(f"  {case.name:14s} ({res.ref_label}) {' '.join(line)}")
    return failures


def describe() -> None:
    """Print what Pinocchio sees in each robot (for the report)."""
    for case in CASES:
        path = urdf_path(case)
        try:
            ref = build_reference(case, path)
        except CaseSkip as exc:
            print(f"{case.name}: SKIP {exc}")
            continue
        kinds = {}
        for j in ref.joints:
            kinds[j.kind] = kinds.get(j.kind, 0) + 1
        mimics = _urdf_mimics(path)
        print(
            f"{case.name:14s} {path.relative_to(robots_dir())}: joints={len(ref.joints)} nq={ref.nq} "
            f"nv={ref.nv} {kinds} mimic tags={len(mimics)} ref={ref.label}"
        )


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--fake-binary":
        sys.exit(fake_binary_main(sys.argv[2:]))
    if len(sys.argv) > 1 and sys.argv[1] == "--describe":
        describe()
        sys.exit(0)
    if len(sys.argv) > 1 and sys.argv[1] == "--self-check":
        sys.exit(self_check())
    if len(sys.argv) > 1 and sys.argv[1] == "--report":
        print(f"worst ||ours-ref||/max(1,||ref||) over {N_STATES} states, binary {binary_path()}")
        sys.exit(1 if summarize([str(binary_path())]) else 0)
    print("usage: test_pinocchio_reference.py --self-check | --report | --describe  (or run it with pytest)")
    sys.exit(2)
