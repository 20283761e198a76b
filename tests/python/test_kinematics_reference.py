"""Reference test: frame kinematics of our ``spatial_dynamics eval`` against Pinocchio.

Pinocchio (PyPI ``pin``) is the independent reference; the robots come from PyPI
``example-robot-data`` (URDF only). For every case we start ONE ``spatial_dynamics eval`` process
and stream ``N_STATES`` random states through it; for every URDF link that both models know as a
frame (links fused through fixed joints, locked or frozen by a reduction, and fixed to the world
included) we ask for

* ``frame_placement``  <-> ``data.oMf[frame]`` after ``pin.framesForwardKinematics``;
* ``frame_jacobian`` in ``world``, ``local`` and ``local_world_aligned``
  <-> ``pin.computeFrameJacobian(..., pin.WORLD | pin.LOCAL | pin.LOCAL_WORLD_ALIGNED)``;
* ``frame_acceleration`` in ``local`` and ``local_world_aligned``
  <-> ``pin.getFrameClassicalAcceleration`` after ``pin.forwardKinematics(q, v, a)``;

and once per state ``center_of_mass`` <-> ``pin.centerOfMass`` (``data.mass[0]``, ``data.com[0]``)
and ``pin.jacobianCenterOfMass``. Every answer must agree with::

    ||ours - ref|| <= REL_TOL * max(1, ||ref||)      (2-norm; Frobenius for matrices)

Coordinates are mapped exactly as in ``test_pinocchio_reference.py`` (joints matched by name,
the floating base by type, continuous joints' (cos, sin) <-> angle; mimic tags ignored in both):
its ``Mapping``, ``sample_state`` and model building are imported from there. Jacobian columns
map like any velocity-space vector (``J_ref[:, perm] = J_ours``); rows are [linear; angular] in
both.

Reduced cases: our ``--lock NAME=VALUE`` / ``--tip LINK`` against ``pin.buildReducedModel`` with
the same joints locked at the same positions (the rest at ``pin.neutral``).

The binary: ``$SPATIAL_DYNAMICS_BIN`` or ``<repo>/target/release/spatial_dynamics``; missing, the
tests FAIL. ``python tests/python/test_kinematics_reference.py --report`` prints the worst
relative error per case and quantity.
"""

from __future__ import annotations

import json
import math
import sys
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pinocchio_cases import (  # noqa: E402  (shared with the other reference tests)
    _BAXTER,
    _PANDA,
    _SOLO12,
    _TALOS,
    _UR5,
    Case,
    LayoutError,
    Mapping,
    NativeRef,
    binary_path,
    build_pin_model,
    cached,
    require_binary,
    run_command,
    run_eval,
    sample_state,
    urdf_path,
)

try:  # pytest is only needed for the test run, not for --report
    import pytest
except ImportError:  # pragma: no cover
    pytest = None

REL_TOL = 1e-12
N_STATES = 4
SEED = 20250121

REFERENCES = {
    "world": pin.ReferenceFrame.WORLD,
    "local": pin.ReferenceFrame.LOCAL,
    "local_world_aligned": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
}
ACCELERATION_REFERENCES = ("local", "local_world_aligned")
QUANTITIES = (
    "placement",
    *(f"jacobian_{r}" for r in REFERENCES),
    *(f"acceleration_{r}" for r in ACCELERATION_REFERENCES),
    "mass",
    "com",
    "com_jacobian",
)


@dataclass(frozen=True)
class KinCase:
    name: str
    urdf: tuple
    floating: bool = False
    locks: tuple = ()  # ((joint, position), ...): our --lock, pin's reduced model
    tips: tuple = ()  # our --tip; pin locks every joint not on the paths root -> tips
    fused_expected: bool = True  # the robot has links fused through fixed joints

    def our_flags(self):
        flags = ["--floating-base"] if self.floating else []
        flags.append("--ignore-mimic")
        for name, value in self.locks:
            flags += ["--lock", f"{name}={value!r}"]
        for tip in self.tips:
            flags += ["--tip", tip]
        return flags


CASES = (
    KinCase("ur5", _UR5),
    KinCase("panda", _PANDA),
    KinCase("baxter", _BAXTER),
    KinCase("solo12", _SOLO12, floating=True),
    KinCase("talos", _TALOS, floating=True),
    KinCase("ur5_locked", _UR5, locks=(("shoulder_lift_joint", 0.4), ("wrist_2_joint", -0.7))),
    KinCase("panda_tip", _PANDA, tips=("panda_link5",)),
    KinCase("talos_right_leg", _TALOS, tips=("leg_right_6_link",)),
)


# ----------------------------------------------------------------------------------------------
# Pinocchio side
# ----------------------------------------------------------------------------------------------


def _path_joints(model, tips):
    """Pinocchio joint ids on the paths from the root to the tips' frames."""
    keep = set()
    for tip in tips:
        j = model.frames[model.getFrameId(tip)].parentJoint
        while j > 0:
            keep.add(j)
            j = model.parents[j]
    return keep


def build_reference(case: KinCase, path):
    full = build_pin_model(path, case.floating)
    if not (case.locks or case.tips):
        return full
    q_ref = pin.neutral(full)
    lock = set()
    for name, value in case.locks:
        j = full.getJointId(name)
        q_ref[full.joints[j].idx_q] = value
        lock.add(j)
    if case.tips:
        keep = _path_joints(full, case.tips)
        lock |= {j for j in range(1, full.njoints) if j not in keep}
    return pin.buildReducedModel(full, sorted(lock), q_ref)


def urdf_links(path):
    """(link names in document order, names of links whose parent joint is fixed)."""
    root = ET.parse(path).getroot()
    links = [link.get("name") for link in root.iter("link")]
    fused = {j.find("child").get("link") for j in root.iter("joint") if j.get("type") == "fixed"}
    return links, fused


def pin_frame(model, link):
    if model.existFrame(link, pin.FrameType.BODY):
        return model.getFrameId(link, pin.FrameType.BODY)
    if model.existFrame(link):
        return model.getFrameId(link)
    return None


# ----------------------------------------------------------------------------------------------
# Running one case
# ----------------------------------------------------------------------------------------------


@dataclass
class CaseResult:
    path: Path = None
    error: str = ""
    layout_error: str = ""
    frames: list = field(default_factory=list)  # link names compared
    fused: list = field(default_factory=list)  # of those, links reached through fixed joints
    # quantity -> [(what, err, ref norm, bound)]
    records: dict = field(default_factory=dict)
    bad_answers: dict = field(default_factory=dict)  # quantity -> [message]


def compute_case(case: KinCase, command: list) -> CaseResult:
    res = CaseResult()
    res.path = urdf_path(Case(case.name, case.urdf))
    model = build_reference(case, res.path)
    ref = NativeRef(model, "pinocchio")
    data = ref.data
    flags = ["--urdf", str(res.path), *case.our_flags()]
    out = run_command([*command, "model", *flags, "--json"])
    if out.returncode != 0:
        res.error = f"model --json exited {out.returncode}: {out.stderr.strip()[:2000]}"
        return res
    try:
        mapping = Mapping.build(json.loads(out.stdout), ref)
    except LayoutError as exc:
        res.layout_error = str(exc)
        return res

    links, fused = urdf_links(res.path)
    frames = [(link, pin_frame(model, link)) for link in links]
    res.frames = [link for link, fid in frames if fid is not None]
    res.fused = [link for link in res.frames if link in fused]

    rng = np.random.default_rng(SEED ^ zlib.crc32(case.name.encode()))
    lines, expected = [], []  # expected[k] = (quantity, what, reference value, key in the answer)
    for i in range(N_STATES):
        q, v, a, _ = sample_state(ref, rng)
        q_ours = mapping.q_to_ours(q)
        q = mapping.q_to_ref(q_ours)
        qo, vo, ao = q_ours.tolist(), mapping.v_to_ours(v).tolist(), mapping.v_to_ours(a).tolist()
        pin.forwardKinematics(model, data, q, v, a)
        pin.updateFramePlacements(model, data)
        for link, fid in frames:
            if fid is None:
                continue
            what = f"state {i}, link {link}"
            oMf = data.oMf[fid]
            lines.append({"op": "frame_placement", "q": qo, "frame": link})
            expected.append(("placement", what, np.concatenate([oMf.translation, oMf.rotation.ravel()]), None))
            for name in ACCELERATION_REFERENCES:
                acc = pin.getFrameClassicalAcceleration(model, data, fid, REFERENCES[name])
                lines.append({"op": "frame_acceleration", "q": qo, "v": vo, "a": ao, "frame": link, "reference": name})
                expected.append((f"acceleration_{name}", what, np.concatenate([acc.linear, acc.angular]), None))
        for link, fid in frames:
            if fid is None:
                continue
            for name, reference in REFERENCES.items():
                j = pin.computeFrameJacobian(model, data, q, fid, reference).copy()
                lines.append({"op": "frame_jacobian", "q": qo, "frame": link, "reference": name})
                expected.append((f"jacobian_{name}", f"state {i}, link {link}", j, None))
        com = pin.centerOfMass(model, data, q).copy()
        jcom = pin.jacobianCenterOfMass(model, data, q).copy()
        lines.append({"op": "center_of_mass", "q": qo})
        expected.append(("com_all", f"state {i}", (float(data.mass[0]), com, jcom), None))

    answers, res.error = run_eval(command, flags, lines)
    if res.error:
        return res

    def record(quantity, what, got, want):
        err = float(np.linalg.norm(got - want))
        ref_norm = float(np.linalg.norm(want))
        res.records.setdefault(quantity, []).append(
            (what, err if math.isfinite(err) else math.inf, ref_norm, REL_TOL * max(1.0, ref_norm))
        )

    for (quantity, what, want, _), line in zip(expected, answers):
        ans = json.loads(line)
        if "error" in ans:
            bucket = ("mass", "com", "com_jacobian") if quantity == "com_all" else (quantity,)
            for qn in bucket:
                res.bad_answers.setdefault(qn, []).append(f"{what}: error answer: {ans['error']}")
            continue
        try:
            if quantity == "placement":
                got = np.concatenate([np.array(ans["translation"], float), np.array(ans["rotation"], float).ravel()])
            elif quantity.startswith("acceleration"):
                got = np.array(ans["acceleration"], float)
            elif quantity.startswith("jacobian"):
                got = mapping_columns(mapping, np.array(ans["J"], float).reshape(6, -1))
            else:
                mass, com, jcom = want
                record("mass", what, np.array([float(ans["mass"])]), np.array([mass]))
                record("com", what, np.array(ans["com"], float), com)
                got_j = mapping_columns(mapping, np.array(ans["J"], float).reshape(3, -1))
                record("com_jacobian", what, got_j, jcom)
                continue
            if got.shape != want.shape:
                raise ValueError(f"shape {got.shape}, expected {want.shape}")
        except (KeyError, TypeError, ValueError) as exc:
            res.bad_answers.setdefault(quantity, []).append(f"{what}: malformed answer ({exc!r}): {line[:300]}")
            continue
        record(quantity, what, got, want)
    return res


def mapping_columns(mapping, j_ours):
    """Our columns (our v order) into Pinocchio's v order."""
    out = np.zeros((j_ours.shape[0], mapping.ref_nv))
    out[:, mapping.perm] = j_ours
    return out


_RESULTS: dict = {}


def case_result(case: KinCase, command=None) -> CaseResult:
    return cached(_RESULTS, compute_case, case, command)


def check(case: KinCase, quantity: str, res: CaseResult):
    """(ok, message)."""
    where = f"{case.name} ({res.path.name}, flags {' '.join(case.our_flags())})"
    if res.error:
        return False, f"{where}: {res.error}"
    if res.layout_error:
        return False, f"{where}: layout mismatch: {res.layout_error}"
    msgs = [*res.bad_answers.get(quantity, [])[:5]]
    recs = res.records.get(quantity, [])
    if not recs and not msgs:
        msgs.append("nothing compared")
    failing = [r for r in recs if not r[1] <= r[3]]
    if failing:
        worst = max(failing, key=lambda r: r[1] / r[3])
        msgs.append(
            f"{len(failing)}/{len(recs)} answers exceed ||ours-ref|| <= {REL_TOL:g}*max(1,||ref||); worst: "
            f"{worst[0]}: ||err||={worst[1]:.3e}, ||ref||={worst[2]:.3e}, bound={worst[3]:.3e}"
        )
    return (not msgs), f"{where} {quantity}: " + "; ".join(msgs)


# ----------------------------------------------------------------------------------------------
# pytest
# ----------------------------------------------------------------------------------------------

if pytest is not None:

    @pytest.mark.parametrize("quantity", QUANTITIES)
    @pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
    def test_kinematics_against_pinocchio(case, quantity):
        require_binary()
        ok, msg = check(case, quantity, case_result(case))
        if not ok:
            pytest.fail(msg, pytrace=False)

    @pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
    def test_every_link_is_compared(case):
        """Every URDF link Pinocchio knows as a frame is compared, fused ones included."""
        require_binary()
        res = case_result(case)
        links, fused = urdf_links(res.path)
        assert res.frames == links, f"links Pinocchio has no frame for: {sorted(set(links) - set(res.frames))}"
        if case.fused_expected:
            assert res.fused, f"{case.name}: no link reached through a fixed joint was compared"


def report(command) -> int:
    for case in CASES:
        res = case_result(case, command)
        print(f"{case.name}: {len(res.frames)} frames ({len(res.fused)} fused) {res.error or res.layout_error}")
        for quantity in QUANTITIES:
            recs = res.records.get(quantity, [])
            worst = max((r[1] / max(1.0, r[2]) for r in recs), default=float("nan"))
            bad = len(res.bad_answers.get(quantity, []))
            print(f"  {quantity:32s} worst relative error {worst:.2e} over {len(recs)}" + (f", {bad} errors" if bad else ""))
    return 0


if __name__ == "__main__":
    if "--report" in sys.argv:
        sys.exit(report([str(binary_path())]))
    print(__doc__)
