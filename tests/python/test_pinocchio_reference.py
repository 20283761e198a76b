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

import glob
import json
import math
import os
import site
import subprocess
import sys
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

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
EVAL_TIMEOUT_S = 600
# Our eval answers forward_dynamics method "aba" with an error when a joint mimics another
# (mimic honoured), exactly as pin.aba does ("does not support Joint Mimic"); that refusal is
# the documented contract, so it passes when it names "mimic" and covers every state (anything
# less fails). Numbers, if given instead, are compared like any other.
MIMIC_ABA_REFUSAL_OK = True

REPO = Path(__file__).resolve().parents[2]
DEFAULT_BIN = REPO / "target" / "release" / "spatial_dynamics"

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


@dataclass(frozen=True)
class Case:
    name: str
    urdf: tuple  # candidate paths relative to example-robot-data's robots/ directory
    floating: bool = False
    mimic: str = ""  # "" = mimic ignored in both; "native" / "projected" = mimic honoured
    # Reduction: our flags (--root/--tip), and the prefix of the joints that stay moving; the
    # reference is pin.buildReducedModel locking every other joint at pin.neutral.
    reduce: tuple = ()
    keep: str = ""

    def our_flags(self):
        flags = ["--floating-base"] if self.floating else []
        if not self.mimic:
            flags.append("--ignore-mimic")
        return flags + list(self.reduce)


_UR5 = ("ur_description/urdf/ur5_robot.urdf",)
_PANDA = ("panda_description/urdf/panda.urdf",)
_BAXTER = ("baxter_description/urdf/baxter.urdf",)
_TALOS = ("talos_data/robots/talos_full_v2.urdf", "talos_data/robots/talos_full.urdf")
_SOLO12 = ("solo_description/robots/solo12.urdf",)
_ANYMAL = ("anymal_b_simple_description/robots/anymal.urdf", "anymal_description/robots/anymal.urdf")
_KINOVA = ("kinova_description/robots/kinova.urdf",)
# Ours: joints placed by quarter turns, whose bodies our model turns (src/core/model/orientation.rs).
_QUARTER_TURNS = (str(REPO / "src" / "core" / "tests" / "models" / "quarter_turns.urdf"),)

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


class LayoutError(Exception):
    """Our model --json does not describe the same coordinates as Pinocchio's model."""


class CaseSkip(Exception):
    """The reference cannot be built with the installed Pinocchio (reason in the message)."""


# ----------------------------------------------------------------------------------------------
# Locating things
# ----------------------------------------------------------------------------------------------


def binary_path() -> Path:
    env = os.environ.get("SPATIAL_DYNAMICS_BIN")
    return Path(env) if env else DEFAULT_BIN


def _robots_dir_candidates():
    env = os.environ.get("EXAMPLE_ROBOT_DATA_DIR")
    if env:
        yield Path(env)
    try:  # example-robot-data < 5 ships a Python module; >= 5 (cmeel wheel) only data files
        from example_robot_data.robots_loader import getModelPath  # type: ignore

        yield Path(getModelPath("ur_description/urdf/ur5_robot.urdf"))
        yield Path(getModelPath("ur_description/urdf/ur5_robot.urdf")) / "robots"
    except Exception:
        pass
    roots = [sys.prefix, sys.base_prefix, *site.getsitepackages()]
    for root in roots:
        for pattern in (
            "lib/python*/site-packages/cmeel.prefix/share/example-robot-data/robots",
            "cmeel.prefix/share/example-robot-data/robots",
            "share/example-robot-data/robots",
        ):
            for hit in sorted(glob.glob(os.path.join(root, pattern))):
                yield Path(hit)
    yield Path("/opt/openrobots/share/example-robot-data/robots")


def robots_dir() -> Path:
    for cand in _robots_dir_candidates():
        if (cand / "ur_description").is_dir():
            return cand
    raise FileNotFoundError(
        "example-robot-data robots/ directory not found (pip install example-robot-data, "
        "or set EXAMPLE_ROBOT_DATA_DIR)"
    )


def urdf_path(case: Case) -> Path:
    if all(Path(rel).is_absolute() for rel in case.urdf):
        return Path(case.urdf[0])
    base = robots_dir()
    for rel in case.urdf:
        if (base / rel).is_file():
            return base / rel
    raise FileNotFoundError(f"{case.name}: none of {case.urdf} under {base}")


# ----------------------------------------------------------------------------------------------
# Pinocchio side
# ----------------------------------------------------------------------------------------------


@dataclass
class RefJoint:
    name: str
    kind: str  # revolute | continuous | prismatic | floating
    idx_q: int
    nq: int
    idx_v: int
    nv: int
    lower: np.ndarray
    upper: np.ndarray


def _kind_of(jmodel) -> str:
    short = jmodel.shortname()
    nq, nv = jmodel.nq, jmodel.nv
    if "FreeFlyer" in short:
        return "floating"
    if "Planar" in short:
        return "planar"
    if (nq, nv) == (2, 1):
        return "continuous"  # JointModelRUBX/Y/Z, JointModelRevoluteUnboundedUnaligned
    if (nq, nv) == (1, 1):
        return "prismatic" if ("Prismatic" in short or short.startswith("JointModelP")) else "revolute"
    return short


def _ref_joints(model) -> list:
    out = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        if jm.nv == 0:  # JointModelMimic: no coordinate of its own
            continue
        out.append(
            RefJoint(
                model.names[j],
                _kind_of(jm),
                jm.idx_q,
                jm.nq,
                jm.idx_v,
                jm.nv,
                np.array(model.lowerPositionLimit[jm.idx_q : jm.idx_q + jm.nq]),
                np.array(model.upperPositionLimit[jm.idx_q : jm.idx_q + jm.nq]),
            )
        )
    return out


def _sym(m):
    m = np.array(m)
    return np.triu(m) + np.triu(m, 1).T  # crba fills (at least) the upper triangle


def _urdf_mimics(path) -> list:
    """[(mimic joint, primary joint, multiplier, offset)] from the URDF's <mimic> tags."""
    out = []
    for joint in ET.parse(path).getroot().iter("joint"):
        tag = joint.find("mimic")
        if tag is not None:
            out.append(
                (
                    joint.get("name"),
                    tag.get("joint"),
                    float(tag.get("multiplier", "1")),
                    float(tag.get("offset", "0")),
                )
            )
    return out


def build_pin_model(path, floating: bool, mimic: bool = False):
    args = [str(path)]
    if floating:
        args.append(pin.JointModelFreeFlyer())
    return pin.buildModelFromUrdf(*args, mimic=True) if mimic else pin.buildModelFromUrdf(*args)


class NativeRef:
    """Pinocchio's own model (mimic ignored, or native JointModelMimic)."""

    def __init__(self, model, label):
        self.model = model
        self.data = model.createData()
        self.label = label
        self.joints = _ref_joints(model)
        self.nq, self.nv = model.nq, model.nv
        self.has_mimic = any(model.joints[j].nv == 0 for j in range(1, model.njoints))

    def rnea(self, q, v, a):
        return pin.rnea(self.model, self.data, q, v, a).copy()

    def mass_matrix(self, q):
        return _sym(pin.crba(self.model, self.data, q))

    def gravity(self, q):
        return pin.computeGeneralizedGravity(self.model, self.data, q).copy()

    def forward_dynamics(self, q, v, tau):
        if self.has_mimic:  # pin.aba: "This algorithm does not support Joint Mimic type"
            nle = pin.nonLinearEffects(self.model, self.data, q, v).copy()
            return np.linalg.solve(self.mass_matrix(q), tau - nle)
        return pin.aba(self.model, self.data, q, v, tau).copy()


class ProjectedMimicRef:
    """Pinocchio's mimic-ignored model, constrained by the URDF's mimic map (see docstring)."""

    def __init__(self, path, floating):
        self.full = NativeRef(build_pin_model(path, floating), "pinocchio (mimic ignored)")
        self.label = "pinocchio, mimic-ignored model projected through the mimic map"
        model = self.full.model
        by_name = {j.name: j for j in self.full.joints}
        mimics = _urdf_mimics(path)
        mimic_names = {m[0] for m in mimics}
        self.joints, q_of, v_of = [], {}, {}
        nq = nv = 0
        for j in self.full.joints:
            if j.name in mimic_names:
                continue
            self.joints.append(RefJoint(j.name, j.kind, nq, j.nq, nv, j.nv, j.lower, j.upper))
            q_of[j.name], v_of[j.name] = nq, nv
            nq, nv = nq + j.nq, nv + j.nv
        self.nq, self.nv = nq, nv
        # q_full = Sq q + q_offset (mimic joints are 1-dof revolute/prismatic); v_full = G v
        self.Sq = np.zeros((model.nq, nq))
        self.q_offset = np.zeros(model.nq)
        self.G = np.zeros((model.nv, nv))
        for j in self.joints:
            fj = by_name[j.name]
            self.Sq[fj.idx_q : fj.idx_q + fj.nq, j.idx_q : j.idx_q + j.nq] = np.eye(j.nq)
            self.G[fj.idx_v : fj.idx_v + fj.nv, j.idx_v : j.idx_v + j.nv] = np.eye(j.nv)
        self.mimic_rows = []  # (row in q_full, row in v_full) of each mimic joint
        for name, primary, mult, offset in mimics:
            mj, pj = by_name[name], by_name[primary]
            self.mimic_rows.append((mj.idx_q, mj.idx_v))
            if primary in mimic_names or (mj.nq, mj.nv, pj.nq, pj.nv) != (1, 1, 1, 1):
                raise CaseSkip(f"mimic {name} <- {primary}: only 1-dof, non-chained mimics are projected")
            self.Sq[mj.idx_q, q_of[primary]] = mult
            self.q_offset[mj.idx_q] = offset
            self.G[mj.idx_v, v_of[primary]] = mult

    def _q(self, q):
        return self.Sq @ q + self.q_offset

    def rnea(self, q, v, a):
        return self.G.T @ self.full.rnea(self._q(q), self.G @ v, self.G @ a)

    def mass_matrix(self, q):
        return self.G.T @ self.full.mass_matrix(self._q(q)) @ self.G

    def gravity(self, q):
        return self.G.T @ self.full.gravity(self._q(q))

    def forward_dynamics(self, q, v, tau):
        qf = self._q(q)
        nle = self.G.T @ pin.nonLinearEffects(self.full.model, self.full.data, qf, self.G @ v)
        return np.linalg.solve(self.mass_matrix(q), tau - nle)


def build_reference(case: Case, path):
    if case.keep:
        full = build_pin_model(path, case.floating)
        lock = [j for j in range(1, full.njoints) if not full.names[j].startswith(case.keep)]
        reduced = pin.buildReducedModel(full, lock, pin.neutral(full))
        assert reduced.nv == sum(n.startswith(case.keep) for n in full.names), case.name
        return NativeRef(reduced, f"pinocchio buildReducedModel (all but {case.keep}* locked at neutral)")
    if case.mimic == "projected":
        return ProjectedMimicRef(path, case.floating)
    if case.mimic == "native":
        try:
            model = build_pin_model(path, case.floating, mimic=True)
        except TypeError as exc:
            raise CaseSkip(f"installed pin {pin.__version__} has no buildModelFromUrdf(..., mimic=True): {exc}")
        except Exception as exc:
            raise CaseSkip(f"pin {pin.__version__} cannot build {path.name} with mimic=True: {exc}")
        return NativeRef(model, "pinocchio (native mimic=True)")
    return NativeRef(build_pin_model(path, case.floating), "pinocchio")


def sample_state(ref, rng):
    """One random state in Pinocchio's convention: q (ref nq), v, a, tau (ref nv)."""
    q = np.zeros(ref.nq)
    for j in ref.joints:
        s = slice(j.idx_q, j.idx_q + j.nq)
        if j.kind == "floating":
            quat = rng.standard_normal(4)
            q[s] = np.concatenate([rng.uniform(-1.0, 1.0, 3), quat / np.linalg.norm(quat)])
        elif j.kind == "continuous":
            t = rng.uniform(-math.pi, math.pi)
            q[s] = [math.cos(t), math.sin(t)]
        elif j.kind in ("revolute", "prismatic"):
            lo, hi = float(j.lower[0]), float(j.upper[0])
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                lo, hi = (-math.pi, math.pi) if j.kind == "revolute" else (-1.0, 1.0)
            q[s] = rng.uniform(lo, hi)
        else:
            raise LayoutError(f"cannot sample joint {j.name} of kind {j.kind}")
    v, a, tau = (rng.standard_normal(ref.nv) for _ in range(3))
    return q, v, a, tau


# ----------------------------------------------------------------------------------------------
# Mapping between our coordinates and Pinocchio's
# ----------------------------------------------------------------------------------------------

_OUR_NQ = {"revolute": 1, "continuous": 1, "prismatic": 1, "floating": 7}


@dataclass
class Mapping:
    """Built from our `model --json` and the reference's joints; see the module docstring."""

    our_nq: int
    our_nv: int
    ref_nq: int
    ref_nv: int
    blocks: list = field(default_factory=list)  # (kind, our q_index, ref idx_q, nq_ours)
    perm: np.ndarray = None  # x_ours = x_ref[perm] for v-space vectors

    @classmethod
    def build(cls, ours: dict, ref) -> "Mapping":
        problems = []
        try:
            our_joints = list(ours["joints"])
            our_nq, our_nv = int(ours["nq"]), int(ours["nv"])
        except (KeyError, TypeError, ValueError) as exc:
            raise LayoutError(f"model --json lacks nq/nv/joints: {exc!r}: {ours!r}"[:2000])
        ref_by_name = {j.name: j for j in ref.joints if j.kind != "floating"}
        ref_floating = [j for j in ref.joints if j.kind == "floating"]
        our_floating = [j for j in our_joints if j.get("type") == "floating"]
        if len(ref_floating) != len(our_floating):
            problems.append(f"floating joints: ours {len(our_floating)}, pinocchio {len(ref_floating)}")
        if our_nv != ref.nv:
            problems.append(f"nv: ours {our_nv}, pinocchio {ref.nv}")
        our_names = {j.get("name") for j in our_joints if j.get("type") != "floating"}
        only_ours = sorted(our_names - set(ref_by_name))
        only_ref = sorted(set(ref_by_name) - our_names)
        if only_ours:
            problems.append(f"joints only in ours: {only_ours}")
        if only_ref:
            problems.append(f"joints only in pinocchio: {only_ref}")
        if len(our_names) != len(our_joints) - len(our_floating):
            problems.append("duplicate joint names in ours")

        m = cls(our_nq, our_nv, ref.nq, ref.nv)
        perm = np.full(our_nv, -1, dtype=int)
        q_cover = np.zeros(our_nq, dtype=int)
        expected_nq = 0
        for oj in our_joints:
            typ = oj.get("type")
            if typ == "floating":
                rj = ref_floating[0] if ref_floating else None
            else:
                rj = ref_by_name.get(oj.get("name"))
            if rj is None:
                continue
            label = f"joint {oj.get('name')!r}"
            if typ != rj.kind:
                problems.append(f"{label}: type ours {typ!r}, pinocchio {rj.kind!r}")
                continue
            if rj.kind not in _OUR_NQ:
                problems.append(f"{label}: kind {rj.kind!r} is not mapped")
                continue
            nq_ours = _OUR_NQ[rj.kind]
            expected_nq += nq_ours
            qi, nq, vi, nv = (int(oj.get(k, -1)) for k in ("q_index", "nq", "v_index", "nv"))
            if nq != nq_ours or nv != rj.nv:
                problems.append(f"{label}: ours nq={nq} nv={nv}, expected nq={nq_ours} nv={rj.nv}")
                continue
            if qi < 0 or qi + nq > our_nq or vi < 0 or vi + nv > our_nv:
                problems.append(f"{label}: q_index={qi} v_index={vi} out of range")
                continue
            q_cover[qi : qi + nq] += 1
            perm[vi : vi + nv] = np.arange(rj.idx_v, rj.idx_v + rj.nv)
            m.blocks.append((rj.kind, qi, rj.idx_q, nq))
        if expected_nq != our_nq:
            problems.append(f"nq: ours {our_nq}, expected {expected_nq} from pinocchio's joints")
        if not problems and (np.any(q_cover != 1) or np.any(perm < 0) or len(set(perm)) != our_nv):
            problems.append("our q_index/v_index ranges do not tile the coordinates exactly once")
        if problems:
            raise LayoutError("; ".join(problems))
        m.perm = perm
        return m

    def q_to_ours(self, q_ref):
        out = np.zeros(self.our_nq)
        for kind, qi, ri, n in self.blocks:
            if kind == "continuous":
                out[qi] = math.atan2(q_ref[ri + 1], q_ref[ri])
            else:
                out[qi : qi + n] = q_ref[ri : ri + n]
        return out

    def q_to_ref(self, q_ours):
        out = np.zeros(self.ref_nq)
        for kind, qi, ri, n in self.blocks:
            if kind == "continuous":
                out[ri : ri + 2] = [math.cos(q_ours[qi]), math.sin(q_ours[qi])]
            else:
                out[ri : ri + n] = q_ours[qi : qi + n]
        return out

    def v_to_ours(self, x_ref):
        return np.asarray(x_ref)[self.perm]

    def v_to_ref(self, x_ours):
        out = np.zeros(self.ref_nv)
        out[self.perm] = x_ours
        return out

    def m_to_ref(self, m_ours):
        out = np.zeros((self.ref_nv, self.ref_nv))
        out[np.ix_(self.perm, self.perm)] = m_ours
        return out


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


def _run(cmd, stdin=""):
    return subprocess.run(cmd, input=stdin, capture_output=True, text=True, timeout=EVAL_TIMEOUT_S)


def _fmt_cmd(cmd):
    return " ".join(str(c) for c in cmd)


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
    out = _run(cmd)
    if out.returncode != 0:
        res.error = f"`{_fmt_cmd(cmd)}` exited {out.returncode}: {out.stderr.strip()[:2000]}"
        return res
    try:
        ours = json.loads(out.stdout)
    except json.JSONDecodeError as exc:
        res.error = f"`{_fmt_cmd(cmd)}` printed no JSON ({exc}): {out.stdout[:500]!r}"
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

    cmd = [*command, "eval", *flags]
    out = _run(cmd, "".join(json.dumps(r) + "\n" for r in lines))
    answers = out.stdout.splitlines()
    if out.returncode != 0 or len(answers) != len(lines):
        res.error = (
            f"`{_fmt_cmd(cmd)}` exited {out.returncode} with {len(answers)} answers to {len(lines)} "
            f"requests; stderr: {out.stderr.strip()[:2000]}"
        )
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
    if command is None:
        command = [str(binary_path())]
    key = (case, tuple(command))
    if key not in _RESULTS:
        _RESULTS[key] = compute_case(case, command)
    return _RESULTS[key]


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
        path = binary_path()
        if not (path.is_file() and os.access(path, os.X_OK)):
            pytest.fail(
                f"spatial_dynamics binary missing at {path}: this reference test is required "
                "(cargo build --release, or set SPATIAL_DYNAMICS_BIN)",
                pytrace=False,
            )
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
