"""Reference test: the derivatives of the dynamics (``eval`` ops ``inverse_dynamics_derivatives``
and ``forward_dynamics_derivatives``) against Pinocchio's ``computeRNEADerivatives`` and
``computeABADerivatives`` on UR5, Panda, Baxter, TALOS (fixed and floating) and Solo12::

    ||ours - ref|| <= REL_TOL * max(1, ||ref||)      (Frobenius norm, every matrix, every state)

Coordinates are mapped as in ``test_pinocchio_reference`` (joints by name, the floating base by
type; a matrix by ``M_ours = M_pin[p][:, p]``), whose helpers this file imports. The tangent of
``q`` is the same in both programs: one angle for a revolute or continuous joint (Pinocchio's
(cos, sin) pair moves by a rotation), and for a free-flyer the twist in the base's own frame,
linear then angular (Pinocchio differentiates along ``integrate(q, ε e_k)``, ``M exp(ε e_k)``,
which is our ``Model::integrate``). Mimic joints are ignored in both (``--ignore-mimic``).
Pinocchio fills only the upper triangle of ``M`` (``dtau_da``) and of ``M⁻¹`` (``ddq_dtau``) in
some versions: both are symmetrised from it.

Tolerance: every matrix is compared to ``REL_TOL = 1e-10``. Forward-dynamics derivatives go
through ``M⁻¹`` in both programs, whose rounding is up to ``cond(M) · ε_mach`` relative (cond(M)
up to about 1.2e6 on TALOS, 2.7e-10); measured with pin 4.1 they agree to 9e-13 at worst
(TALOS floating), the inverse-dynamics ones to 2e-15. A failure message prints cond(M), so that
conditioning can be told from a bug. ``python test_derivatives_reference.py`` prints the worst
relative error per case and matrix.
"""

from __future__ import annotations

import json
import math
import os
import zlib

import numpy as np
import pinocchio as pin
import pytest

from pinocchio_cases import (
    _TALOS,
    Case,
    Mapping,
    _sym,
    binary_path,
    build_reference,
    run_command,
    sample_state,
    urdf_path,
)
from test_pinocchio_reference import CASES

REL_TOL = 1e-10
N_STATES = 8
SEED = 20261126

DERIVATIVE_CASES = tuple(c for c in CASES if c.name in ("ur5", "panda", "baxter", "talos", "solo12")) + (
    Case("talos_floating", _TALOS, floating=True),
)

# What each op answers, and the matching part of Pinocchio's result.
OPS = {
    "inverse_dynamics_derivatives": ("dtau_dq", "dtau_dv", "M"),
    "forward_dynamics_derivatives": ("ddq_dq", "ddq_dv", "Minv"),
}


def reference_derivatives(ref, q, v, a, tau):
    """Pinocchio's derivatives at (q, v, a) and at (q, v, tau), full matrices, by our names."""
    model, data = ref.model, ref.data
    dq, dv, da = pin.computeRNEADerivatives(model, data, q, v, a)
    inverse = {"dtau_dq": np.array(dq), "dtau_dv": np.array(dv), "M": _sym(da)}
    dq, dv, dtau = pin.computeABADerivatives(model, data, q, v, tau)
    forward = {"ddq_dq": np.array(dq), "ddq_dv": np.array(dv), "Minv": _sym(dtau)}
    return inverse, forward, np.linalg.cond(inverse["M"])


_RESULTS = {}


def case_records(case: Case):
    """For each matrix name, a list of (state, ||err||, ||ref||, bound, cond(M)); or an error."""
    if case in _RESULTS:
        return _RESULTS[case]
    path = urdf_path(case)
    ref = build_reference(case, path)
    flags = ["--urdf", str(path), *case.our_flags()]
    command = [str(binary_path())]
    out = run_command([*command, "model", *flags, "--json"])
    assert out.returncode == 0, out.stderr
    mapping = Mapping.build(json.loads(out.stdout), ref)
    rng = np.random.default_rng(SEED ^ zlib.crc32(case.name.encode()))
    states, lines = [], []
    for _ in range(N_STATES):
        q, v, a, tau = sample_state(ref, rng)
        q_ours = mapping.q_to_ours(q)
        q = mapping.q_to_ref(q_ours)
        states.append((q, v, a, tau))
        qo, vo, ao, to = q_ours.tolist(), *(mapping.v_to_ours(x).tolist() for x in (v, a, tau))
        lines.append({"op": "inverse_dynamics_derivatives", "q": qo, "v": vo, "a": ao})
        lines.append({"op": "forward_dynamics_derivatives", "q": qo, "v": vo, "tau": to})
    out = run_command([*command, "eval", *flags], "".join(json.dumps(r) + "\n" for r in lines))
    answers = out.stdout.splitlines()
    assert out.returncode == 0 and len(answers) == len(lines), out.stderr[:2000]
    records = {}
    for i, (q, v, a, tau) in enumerate(states):
        inverse, forward, cond = reference_derivatives(ref, q, v, a, tau)
        for line, want_all in zip(answers[2 * i : 2 * i + 2], (inverse, forward)):
            ans = json.loads(line)
            assert "error" not in ans, f"{case.name} state {i}: {ans['error']}"
            for name, want in want_all.items():
                got = mapping.m_to_ref(np.array(ans[name], dtype=float))
                ref_norm = float(np.linalg.norm(want))
                err = float(np.linalg.norm(got - want))
                records.setdefault(name, []).append((i, err, ref_norm, REL_TOL * max(1.0, ref_norm), cond))
    _RESULTS[case] = records
    return records


def test_binary_exists():
    path = binary_path()
    assert path.is_file() and os.access(path, os.X_OK), (
        f"spatial_dynamics binary missing at {path} (cargo build --release, or set SPATIAL_DYNAMICS_BIN)"
    )


@pytest.mark.parametrize("name", [n for names in OPS.values() for n in names])
@pytest.mark.parametrize("case", DERIVATIVE_CASES, ids=[c.name for c in DERIVATIVE_CASES])
def test_derivatives_against_pinocchio(case, name):
    records = case_records(case)[name]
    assert len(records) == N_STATES
    failing = [r for r in records if not (math.isfinite(r[1]) and r[1] <= r[3])]
    assert not failing, (
        f"{case.name} {name}: {len(failing)}/{N_STATES} states exceed the bound; worst: "
        + ", ".join(
            f"state {i}: ||err||={e:.3e} ||ref||={n:.3e} bound={b:.3e} cond(M)={c:.2e}"
            for i, e, n, b, c in sorted(failing, key=lambda r: -r[1] / r[3])[:3]
        )
    )


if __name__ == "__main__":  # worst relative error per case and matrix
    for case in DERIVATIVE_CASES:
        for name, records in case_records(case).items():
            worst = max(records, key=lambda r: r[1] / max(1.0, r[2]))
            print(f"{case.name:16} {name:8} worst ||err||/max(1,||ref||) = {worst[1] / max(1.0, worst[2]):.2e}")
