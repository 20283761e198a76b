"""The double-double reference behind docs/charts/accuracy.svg (src/cli/chart/reference.rs) against
mpmath at 60 digits: benches/conditioning.py's independently written Lagrangian of the planar chain
(_ref_terms) solved with mpmath.lu_solve, on the same doubles (masses, Iyy = m/12, q, v, tau).

The reference is reached through the hidden `spatial_dynamics chart --reference-eval`: one JSON
request per line, {"masses", "q", "v", "tau"} -> {"a_hi", "a_lo"} with a = a_hi + a_lo per joint.
Asserted: ||a_dd - a_mp|| / ||a_mp|| <= 1e-25 (double-double carries ~32 digits, of which cond H
takes a few on long equal-mass chains: measured 3e-28 at n = 24, 2e-27 at n = 64, 6e-26 at
n = 128; the charted errors are >= 1e-17), on well-scaled and graded chains; a bad request is
answered with an error.
"""

import importlib.util
import json
import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

try:
    import mpmath
    from mpmath import mp, mpf
except ImportError as exc:  # a failure, not a skip: setup_python_env.sh installs PyPI 'mpmath'
    raise ImportError("test_chart_reference.py needs PyPI package 'mpmath' (launch_scripts/setup_python_env.sh)") from exc

REPO = Path(__file__).resolve().parents[2]
BINARY = Path(os.environ.get("SPATIAL_DYNAMICS_BIN") or REPO / "target" / "release" / "spatial_dynamics")
_spec = importlib.util.spec_from_file_location("sd_conditioning", REPO / "benches" / "conditioning.py")
cond_mod = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cond_mod)

# (n, r): equal masses, and graded chains (cond H up to ~1e100) whose scaled conditioning is benign.
CASES = [(1, 1.0), (3, 1.0), (8, 1.0), (24, 1.0), (64, 1.0), (6, 1e-3), (12, 1e-8)]


def masses(n, r):
    """m_k = r^k by repeated multiplication, as geometric_masses in reference.rs does (any doubles would do)."""
    out, m = [], 1.0
    for _ in range(n):
        out.append(m)
        m *= r
    return out


@pytest.fixture(scope="module")
def reference_server():
    assert BINARY.is_file(), f"spatial_dynamics binary missing: {BINARY} (cargo build --release or set SPATIAL_DYNAMICS_BIN)"
    p = subprocess.Popen([str(BINARY), "chart", "--reference-eval"], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)

    def ask(request):
        p.stdin.write(json.dumps(request) + "\n")
        p.stdin.flush()
        line = p.stdout.readline()
        assert line, f"reference server exited: {p.stderr.read()}"
        return json.loads(line)

    yield ask
    p.stdin.close()
    assert p.wait(timeout=30) == 0


def mp_solution(ms, q, v, tau):
    """60 digits plus twice the decades between the heaviest and the lightest link: the graded H
    spans that many decades (conditioning.py's rule, doubled for safety)."""
    iyy = [m / 12.0 for m in ms]  # the same rounding as Chain::new (IEEE division)
    spread = math.ceil(math.log10(max(ms) / min(ms)) + math.log10(12.0))
    with mp.workdps(60 + 2 * spread):
        h, c = cond_mod._ref_terms(ms, iyy, q, v)
        rhs = mp.matrix([mpf(float(t)) for t in tau]) - c
        return mp.lu_solve(h, rhs)


@pytest.mark.parametrize("n,r", CASES, ids=[f"n{n}-r{r:g}" for n, r in CASES])
def test_double_double_reference_matches_mpmath(n, r, reference_server):
    ms = masses(n, r)
    states, _ = cond_mod.random_states(n, ms, 2, seed=1000 + n)
    for q, v, tau in states:
        q, v, tau = ([float(x) for x in arr] for arr in (q, v, tau))
        answer = reference_server({"masses": ms, "q": q, "v": v, "tau": tau})
        assert "a_hi" in answer, answer
        a_mp = mp_solution(ms, q, v, tau)
        with mp.workdps(60):
            a_dd = [mpf(hi) + mpf(lo) for hi, lo in zip(answer["a_hi"], answer["a_lo"])]
            err = mp.sqrt(sum((x - y) ** 2 for x, y in zip(a_dd, a_mp)))
            size = mp.sqrt(sum(y**2 for y in a_mp))
            rel = float(err / size)
        assert rel <= 1e-25, f"n={n} r={r:g}: double-double reference off by {rel:.3g} (relative)"
        # And it is better than double: the low parts carry information.
        assert any(lo != 0.0 for lo in answer["a_lo"])


def test_bad_request_is_an_error(reference_server):
    answer = reference_server({"masses": [1.0, 0.0], "q": [0, 0], "v": [0, 0], "tau": [0, 0]})
    assert "error" in answer and "link1" in answer["error"], answer
    answer = reference_server({"masses": [1.0], "q": [0, 0], "v": [0], "tau": [0]})
    assert "error" in answer, answer
    # The server goes on answering after an error.
    ok = reference_server({"masses": [1.0], "q": [0.5], "v": [0.0], "tau": [0.0]})
    # One rod about its end: a = -(m g / 2) sin q / (m / 3).
    expected = -1.5 * 9.81 * np.sin(0.5)
    assert abs(ok["a_hi"][0] - expected) <= 1e-14 * abs(expected)
