#!/usr/bin/env python3
"""Issue 4 ("ill-conditioning"): where does each forward-dynamics method degrade?

Run:  .venv/bin/python benches/conditioning.py [--quick] [--states K] [--ref-max-n N]
Needs: numpy, mpmath (PyPI ``mpmath``) and the release binary (env SPATIAL_DYNAMICS_BIN or
target/release/spatial_dynamics).  Writes target/conditioning.csv and prints markdown tables.

Models: planar serial chains of n links (revolute joints ``j1..jn`` all about y), each link a
1 m rod along -z (joint k+1 at the end of link k), com at the rod's middle, rotational inertia
about the com diag(m/12, m/12, 1e-6 m) (positive definite, triangle inequality holds), masses
m_k = r**k (k = 0..n-1, evaluated as Python floats: for large n and small r they underflow to
subnormals or 0.0 -- such links are massless, and that is recorded).  Gravity (0, 0, -9.81).

Reference (independent of our code): the chain's Lagrangian in absolute angles
phi_k = theta_1 + ... + theta_k (S = lower-triangular ones, phi = S theta):

    p_k   = sum_{j<k} l u(phi_j) + l/2 u(phi_k),  u(phi) = (-sin phi, -cos phi)  (x, z)
    T     = 1/2 phidot^T Hh phidot,  Hh_ij = a_ij cos(phi_i - phi_j),
            a_ij = sum_k m_k w_ki w_kj + delta_ij Iyy_i,  w_kj = 1 (j<k), 1/2 (j=k), 0 (j>k)
    c_i   = sum_j a_ij sin(phi_i - phi_j) phidot_j^2           (velocity-product terms)
    gh_i  = g b_i sin(phi_i),  b_i = m_i/2 + sum_{k>i} m_k      (from V = sum m_k g z_k)
    relative coordinates:  H = S^T Hh S,  C = S^T (c + gh),  H thetaddot = tau - C.

Everything is evaluated with mpmath from the exact binary values that our binary parses (the
URDF numbers are written with repr(), which round-trips), and solved with mpmath.lu_solve.
Working precision: mp.dps = 50 + (digits that cond(H) can destroy); the cond(H) so obtained is
checked afterwards (log10 cond + 50 <= dps, otherwise the solve is repeated with more digits),
so the reference has >= ~50 correct significant digits.  The reference is computed up to
n <= REF_MAX_N (64) for every ratio; chains with a massless (underflowed) link have a singular
H and no reference (every method should then answer an error).

States (seeded numpy RNG): q, v ~ U(-1, 1); tau_i = U(-1, 1) * s_i with s_i = 9.81 *
sum_{k>=i} m_k (k - i + 1/2), the largest gravity torque joint i can see (the "scale of g(q)"
joint by joint: a norm-wide scale would drown the light distal links in enormous torques).

Per (n, r, state, method) the CSV records: status (ok/error) and the error message, the
relative error ||a - a_ref|| / ||a_ref||, the relative residual ||RNEA(q, v, a) - tau|| / ||tau||
(our inverse_dynamics), the joint-scaled residual max_i |RNEA_i - tau_i| / s_i, cond(H) (mpmath
where a reference exists, else numpy on our mass_matrix -- unreliable beyond ~1e16, flagged).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:
    import mpmath
    from mpmath import mp, mpf
except ImportError:  # pragma: no cover
    sys.exit("conditioning.py needs mpmath: .venv/bin/python -m pip install mpmath")

REPO = Path(__file__).resolve().parents[1]
METHODS = ("aba", "crba", "rnea_columns")
NS = (2, 4, 8, 16, 32, 64, 128, 256, 500)
RATIOS = (1.0, 1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
REF_MAX_N = 64
BASE_DPS = 50
EPS = float(np.finfo(float).eps)
G = 9.81  # the binary's default gravity (0, 0, -9.81); the URDF text has no gravity element


def binary_path() -> Path:
    return Path(os.environ.get("SPATIAL_DYNAMICS_BIN") or REPO / "target" / "release" / "spatial_dynamics")


# ------------------------------------------------------------------ models ----------------------
def masses(n: int, r: float) -> list[float]:
    """m_k = r**k as doubles (Python float pow; may underflow to subnormal / 0.0)."""
    return [float(r) ** k for k in range(n)]


def chain_urdf(n: int, r: float) -> tuple[str, list[float], list[float]]:
    """URDF text, the link masses and the link Iyy values exactly as written (repr round-trips)."""
    ms = masses(n, r)
    iyy = [m / 12.0 for m in ms]
    parts = ['<?xml version="1.0"?>', f'<robot name="chain_n{n}_r{r:g}">', '  <link name="base"/>']
    for k in range(n):
        parent = "base" if k == 0 else f"link{k - 1}"
        z = "0" if k == 0 else "-1"
        parts.append(
            f'  <joint name="j{k + 1}" type="revolute"><parent link="{parent}"/>'
            f'<child link="link{k}"/><origin xyz="0 0 {z}" rpy="0 0 0"/><axis xyz="0 1 0"/>'
            f'<limit lower="-10" upper="10" effort="1000" velocity="100"/></joint>'
        )
        m = ms[k]
        parts.append(
            f'  <link name="link{k}"><inertial><origin xyz="0 0 -0.5" rpy="0 0 0"/>'
            f'<mass value="{m!r}"/><inertia ixx="{iyy[k]!r}" ixy="0" ixz="0" iyy="{iyy[k]!r}" '
            f'iyz="0" izz="{1e-6 * m!r}"/></inertial></link>'
        )
    parts.append("</robot>")
    return "\n".join(parts) + "\n", ms, iyy


def torque_scale(ms: list[float]) -> np.ndarray:
    n = len(ms)
    return np.array([G * sum(ms[k] * (k - i + 0.5) for k in range(i, n)) for i in range(n)])


def random_states(n: int, ms: list[float], count: int, seed: int):
    rng = np.random.default_rng(seed)
    s = torque_scale(ms)
    out = []
    for _ in range(count):
        q = rng.uniform(-1, 1, n)
        v = rng.uniform(-1, 1, n)
        tau = rng.uniform(-1, 1, n) * s
        out.append((q, v, tau))
    return out, s


# ------------------------------------------------------------------ reference -------------------
def _ref_terms(ms, iyy, q, v):
    """H (relative coordinates) and C = S^T (c + gh) as mpmath matrices at the current mp.dps."""
    n = len(ms)
    m = [mpf(x) for x in ms]
    inert = [mpf(x) for x in iyy]
    g = mpf(G)  # the double 9.81, exactly as our binary has it
    half = mpf(1) / 2
    tail = [mpf(0)] * (n + 1)  # tail[k] = sum_{k' >= k} m_k'
    for k in range(n - 1, -1, -1):
        tail[k] = tail[k + 1] + m[k]
    phi, phid = [], []
    acc_p, acc_v = mpf(0), mpf(0)
    for k in range(n):
        acc_p += mpf(float(q[k]))
        acc_v += mpf(float(v[k]))
        phi.append(acc_p)
        phid.append(acc_v)
    cs = [mp.cos(p) for p in phi]
    sn = [mp.sin(p) for p in phi]

    def a(i, j):
        if i == j:
            return m[i] / 4 + tail[i + 1] + inert[i]
        jj = max(i, j)
        return m[jj] * half + tail[jj + 1]

    hh = mp.matrix(n, n)
    c = [mpf(0)] * n
    for i in range(n):
        for j in range(n):
            aij = a(i, j)
            hh[i, j] = aij * (cs[i] * cs[j] + sn[i] * sn[j])
            if i != j:
                c[i] += aij * (sn[i] * cs[j] - cs[i] * sn[j]) * phid[j] ** 2
        c[i] += g * (m[i] * half + tail[i + 1]) * sn[i]
    # H = S^T Hh S: H_ij = sum_{p>=i, q>=j} Hh_pq (2-D suffix sums); C_i = sum_{p>=i} c_p.
    h = mp.matrix(n, n)
    col = mp.matrix(n + 1, n + 1)
    for i in range(n - 1, -1, -1):
        for j in range(n - 1, -1, -1):
            col[i, j] = hh[i, j] + col[i + 1, j] + col[i, j + 1] - col[i + 1, j + 1]
            h[i, j] = col[i, j]
    cc = mp.matrix(n, 1)
    run = mpf(0)
    for i in range(n - 1, -1, -1):
        run += c[i]
        cc[i] = run
    return h, cc


def reference(ms, iyy, states, base_dps=BASE_DPS):
    """[(a_ref as np.float64 array, cond(H) float)] per state, or None when H is singular
    (a link mass is exactly 0.0). Also returns the working dps used."""
    if any(m == 0.0 for m in ms):
        return None, 0
    # Digits cond(H) can destroy: about log10(total mass / lightest link's inertia) + n-growth.
    dps = base_dps + int(math.ceil(math.log10(sum(ms)) - math.log10(min(ms)) + math.log10(12.0))) + 2 * len(ms).bit_length() + 10
    out = []
    for q, v, tau in states:
        while True:
            with mp.workdps(dps):
                h, cc = _ref_terms(ms, iyy, q, v)
                rhs = mp.matrix([mpf(float(t)) for t in tau]) - cc
                x = mp.lu_solve(h, rhs)
                cond = mp.norm(h, 1) * mp.norm(mp.inverse(h), 1)
                needed = base_dps + int(mp.ceil(mp.log10(cond))) + 5
                if needed <= dps:
                    n = h.rows
                    d = [1 / mp.sqrt(h[i, i]) for i in range(n)]
                    hs = mp.matrix(n, n)
                    for i in range(n):
                        for j in range(n):
                            hs[i, j] = d[i] * h[i, j] * d[j]
                    cond_s = mp.norm(hs, 1) * mp.norm(mp.inverse(hs), 1)
                    out.append((np.array([float(xi) for xi in x]), float(cond), float(cond_s)))
                    break
            dps = needed + 10
    return out, dps


# ------------------------------------------------------------------ binary ----------------------
class Eval:
    """One `spatial_dynamics eval --urdf FILE` process; requests streamed one line at a time."""

    def __init__(self, urdf_path: Path, binary: Path | None = None):
        binary = binary or binary_path()
        if not binary.is_file():
            raise FileNotFoundError(f"spatial_dynamics binary not found: {binary}")
        self.p = subprocess.Popen(
            [str(binary), "eval", "--urdf", str(urdf_path)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1,
        )

    def __call__(self, req: dict) -> dict:
        self.p.stdin.write(json.dumps(req) + "\n")
        self.p.stdin.flush()
        line = self.p.stdout.readline()
        if not line:
            err = self.p.stderr.read()
            raise RuntimeError(f"eval exited (rc {self.p.wait()}): {err.strip()}")
        return json.loads(line)

    def close(self):
        try:
            self.p.stdin.close()
        except Exception:
            pass
        try:
            self.p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.p.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def lst(x):
    return [float(t) for t in x]


def run_case(n, r, n_states, tmpdir: Path, ref_max_n=REF_MAX_N, seed_base=4):
    """All rows for one (n, r)."""
    text, ms, iyy = chain_urdf(n, r)
    path = tmpdir / f"chain_n{n}_r{r:g}.urdf"
    path.write_text(text)
    seed = seed_base * 1_000_003 + n * 1009 + int(round(-math.log10(r))) if r != 1 else seed_base * 1_000_003 + n * 1009
    states, s = random_states(n, ms, n_states, seed)
    n_zero = sum(1 for m in ms if m == 0.0)
    n_subnormal = sum(1 for m in ms if 0.0 < m < sys.float_info.min)
    t0 = time.perf_counter()
    ref, dps = reference(ms, iyy, states) if n <= ref_max_n else (None, 0)
    t_ref = time.perf_counter() - t0
    rows = []
    with Eval(path) as ev:
        for si, (q, v, tau) in enumerate(states):
            mm = ev({"op": "mass_matrix", "q": lst(q)})
            if ref is not None:
                cond, cond_s, cond_src = ref[si][1], ref[si][2], "mpmath"
            elif "M" in mm:
                with np.errstate(all="ignore"):
                    M = np.array(mm["M"])
                    cond = float(np.linalg.cond(M, 1))
                    dd = 1 / np.sqrt(np.diag(M))
                    cond_s = float(np.linalg.cond(dd[:, None] * M * dd[None, :], 1))
                cond_src = "numpy(our M)"
            else:
                cond, cond_s, cond_src = float("nan"), float("nan"), "none"
            for method in METHODS:
                ans = ev({"op": "forward_dynamics", "q": lst(q), "v": lst(v), "tau": lst(tau), "method": method})
                row = dict(n=n, r=r, state=si, method=method, n_zero_mass=n_zero, n_subnormal_mass=n_subnormal,
                           cond_H=cond, cond_scaled=cond_s, cond_source=cond_src, ref_dps=dps if ref is not None else "",
                           status="", error="", rel_err="", err_over_condscaled_eps="", rel_residual="", scaled_residual="", any_nonfinite="")
                if "a" in ans:
                    a = np.array(ans["a"], dtype=float)
                    row["status"] = "ok"
                    row["any_nonfinite"] = int(not np.all(np.isfinite(a)))
                    if ref is not None:
                        ar = ref[si][0]
                        row["rel_err"] = float(np.linalg.norm(a - ar) / np.linalg.norm(ar))
                        row["err_over_condscaled_eps"] = row["rel_err"] / (cond_s * EPS)
                    if np.all(np.isfinite(a)):
                        idr = ev({"op": "inverse_dynamics", "q": lst(q), "v": lst(v), "a": lst(a)})
                        if "tau" in idr:
                            res = np.array(idr["tau"]) - tau
                            row["rel_residual"] = float(np.linalg.norm(res) / np.linalg.norm(tau))
                            with np.errstate(all="ignore"):
                                sc = np.where(s > 0, np.abs(res) / np.where(s > 0, s, 1), np.abs(res))
                            row["scaled_residual"] = float(np.max(sc))
                        else:
                            row["rel_residual"] = f"ID error: {idr.get('error')}"
                else:
                    row["status"] = "error"
                    row["error"] = ans.get("error", json.dumps(ans))
                rows.append(row)
    return rows, t_ref


# ------------------------------------------------------------------ summary ---------------------
def _f(x):
    return float(x) if x not in ("", None) else None


def fmt(x):
    return "–" if x is None else f"{x:.0e}"


def summarise(rows, ns, ratios):
    """Markdown tables: per-method grids and the 'where it degrades' summary."""
    out = []
    by = {}
    for row in rows:
        by.setdefault((row["method"], row["n"], row["r"]), []).append(row)
    cond, conds = {}, {}
    for row in rows:
        k = (row["n"], row["r"])
        if math.isfinite(float(row["cond_scaled"])):
            conds[k] = max(conds.get(k, 0.0), float(row["cond_scaled"]))
        cond[(row["n"], row["r"])] = max(cond.get((row["n"], row["r"]), 0.0), float(row["cond_H"]))
    out.append("### cond(H) (max over states; mpmath for n <= %d, numpy on our M beyond, '*' = numpy, unreliable > 1e16)\n" % REF_MAX_N)
    out.append("| r \\ n | " + " | ".join(str(n) for n in ns) + " |")
    out.append("|---" * (len(ns) + 1) + "|")
    for r in ratios:
        cells = []
        for n in ns:
            rs = by.get((METHODS[0], n, r), [])
            star = "*" if rs and rs[0]["cond_source"] != "mpmath" else ""
            cells.append(fmt(cond.get((n, r))) + star)
        out.append(f"| {r:g} | " + " | ".join(cells) + " |")
    out.append("")
    out.append("### cond(D^-1/2 H D^-1/2), D = diag(H) (diagonally scaled; same sources; – = singular/unavailable)\n")
    out.append("| r \\ n | " + " | ".join(str(n) for n in ns) + " |")
    out.append("|---" * (len(ns) + 1) + "|")
    for r in ratios:
        out.append(f"| {r:g} | " + " | ".join(fmt(conds.get((n, r))) for n in ns) + " |")
    out.append("")
    out.append("### max over all referenced cases of rel_err / (cond_scaled * eps), per method\n")
    for method in METHODS:
        v = [float(x["err_over_condscaled_eps"]) for x in rows if x["method"] == method and x["err_over_condscaled_eps"] != ""]
        out.append(f"- {method}: {max(v):.3g} over {len(v)} solves" if v else f"- {method}: no data")
    out.append("")
    for method in METHODS:
        out.append(f"### {method}: max relative error vs mpmath (n <= {REF_MAX_N}) / max relative residual "
                   f"(n > {REF_MAX_N}, marked 'res'); 'ERR' = answered an error\n")
        out.append("| r \\ n | " + " | ".join(str(n) for n in ns) + " |")
        out.append("|---" * (len(ns) + 1) + "|")
        for r in ratios:
            cells = []
            for n in ns:
                rs = by.get((method, n, r), [])
                if not rs:
                    cells.append("")
                    continue
                nerr = sum(1 for x in rs if x["status"] == "error")
                errs = [_f(x["rel_err"]) for x in rs if x["status"] == "ok" and _f(x["rel_err"]) is not None]
                resd = [x["rel_residual"] for x in rs if x["status"] == "ok"]
                resd = [float(x) for x in resd if isinstance(x, float) or (isinstance(x, str) and x and not x.startswith("ID"))]
                if nerr == len(rs):
                    cells.append("ERR")
                elif errs:
                    cells.append(fmt(max(errs)) + (f" ({nerr} ERR)" if nerr else ""))
                elif resd:
                    cells.append(fmt(max(resd)) + " res" + (f" ({nerr} ERR)" if nerr else ""))
                else:
                    cells.append("?")
            out.append(f"| {r:g} | " + " | ".join(cells) + " |")
        out.append("")
    # Where it degrades: per method and r, the smallest n with error > 1e-6, > 1e-2, and an error answer.
    out.append("### Where each method degrades (smallest n, per r; '–' = never in the grid)\n")
    out.append("| method | r | err > 1e-6 | err > 1e-2 | residual > 1e-6 | answers an error | first error message |")
    out.append("|---|---|---|---|---|---|---|")
    for method in METHODS:
        for r in ratios:
            f6 = f2 = fres = ferr = None
            msg = ""
            for n in ns:
                for x in by.get((method, n, r), []):
                    e = _f(x["rel_err"]) if x["status"] == "ok" else None
                    res = x["rel_residual"] if x["status"] == "ok" else ""
                    res = float(res) if isinstance(res, float) or (isinstance(res, str) and res and not res.startswith("ID")) else None
                    if x["status"] == "ok" and x["any_nonfinite"]:
                        e = math.inf
                    if e is not None and e > 1e-6 and f6 is None:
                        f6 = n
                    if e is not None and e > 1e-2 and f2 is None:
                        f2 = n
                    if res is not None and res > 1e-6 and fres is None:
                        fres = n
                    if x["status"] == "error" and ferr is None:
                        ferr, msg = n, x["error"]
            short = (msg[:90] + "…") if len(msg) > 90 else msg
            out.append(f"| {method} | {r:g} | {f6 or '–'} | {f2 or '–'} | {fres or '–'} | {ferr or '–'} | {short} |")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--states", type=int, default=3, help="random states per (n, r) (default 3)")
    ap.add_argument("--ref-max-n", type=int, default=REF_MAX_N)
    ap.add_argument("--quick", action="store_true", help="n <= 16 only")
    ap.add_argument("--csv", default=str(REPO / "target" / "conditioning.csv"))
    args = ap.parse_args(argv)
    ns = [n for n in NS if not args.quick or n <= 16]
    t_start = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory(prefix="sd_conditioning_") as td:
        for n in ns:
            for r in RATIOS:
                t0 = time.perf_counter()
                case_rows, t_ref = run_case(n, r, args.states, Path(td), ref_max_n=args.ref_max_n)
                rows.extend(case_rows)
                print(f"n={n:4d} r={r:<6g} ref {t_ref:6.2f}s total {time.perf_counter() - t0:6.2f}s",
                      file=sys.stderr, flush=True)
    Path(args.csv).parent.mkdir(parents=True, exist_ok=True)
    with open(args.csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print(summarise(rows, ns, list(RATIOS)))
    print(f"\nwrote {args.csv} ({len(rows)} rows) in {time.perf_counter() - t_start:.1f} s")


if __name__ == "__main__":
    main()
