"""What the reference tests against Pinocchio share (test_pinocchio_reference.py,
test_kinematics_reference.py, and what imports them): the cases (a name, the URDF found in
PyPI ``example-robot-data`` or in the repository, the flags), the binary's path, Pinocchio's
model of a case (native mimic joints, or projected), random states, the name-based index maps
between our coordinates and Pinocchio's, running the binary, and the per-case results kept
once computed. The conventions are described in test_pinocchio_reference.py's docstring."""

from __future__ import annotations
import glob
import json
import math
import os
import site
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
import numpy as np
import pinocchio as pin

EVAL_TIMEOUT_S = 600
REPO = Path(__file__).resolve().parents[2]
DEFAULT_BIN = REPO / "target" / "release" / "spatial_dynamics"


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
# Running the binary, once per case
# ----------------------------------------------------------------------------------------------


def run_command(cmd, stdin=""):
    """The finished process of `cmd` (text, output captured)."""
    return subprocess.run(cmd, input=stdin, capture_output=True, text=True, timeout=EVAL_TIMEOUT_S)


def format_command(cmd):
    return " ".join(str(c) for c in cmd)


def run_eval(command, flags, requests):
    """One `eval` process answering `requests` (one JSON line each): (the answer lines, and an
    error naming the command when it failed or answered a different number of lines)."""
    cmd = [*command, "eval", *flags]
    out = run_command(cmd, "".join(json.dumps(r) + "\n" for r in requests))
    answers = out.stdout.splitlines()
    if out.returncode != 0 or len(answers) != len(requests):
        return answers, (
            f"`{format_command(cmd)}` exited {out.returncode} with {len(answers)} answers to "
            f"{len(requests)} requests; stderr: {out.stderr.strip()[:2000]}"
        )
    return answers, ""


def cached(results: dict, compute, case, command=None):
    """`compute(case, command)` (the command defaulting to the binary), computed once per case
    and command and kept in `results`."""
    command = command or [str(binary_path())]
    key = (case, tuple(command))
    if key not in results:
        results[key] = compute(case, command)
    return results[key]


def require_binary():
    """Fails the test (these reference tests are required) when the binary is not there."""
    import pytest

    path = binary_path()
    if not (path.is_file() and os.access(path, os.X_OK)):
        pytest.fail(
            f"spatial_dynamics binary missing at {path}: this reference test is required "
            "(cargo build --release, or set SPATIAL_DYNAMICS_BIN)",
            pytrace=False,
        )
