#!/usr/bin/env python3
"""Counts the floating-point operations each kernel executes, independently of the table in
src/core/plan/flops.rs, and prints table against measurement.

Method: `benches/flop_harness.rs` calls one kernel CALLS times; valgrind's callgrind
(`--dump-instr=yes`) gives how often every machine instruction ran; `objdump -d` says what
each instruction is. Each executed SSE/AVX/x87 arithmetic instruction counts as the number of
double-precision operations it performs: `addsd`/`subsd` 1 add, `mulsd` 1 mul, `divsd` 1 div,
`sqrtsd` 1 sqrt; the packed forms (`addpd` …) 2 on an xmm register, 4 on a ymm one; a fused
multiply-add 1 mul + 1 add per lane. Moves, shuffles, negations (`xorpd`), absolute values
(`andpd`), comparisons (`ucomisd`, `cmp*`, `min*`, `max*`) and conversions are not FLOPs, as in
the table. Two runs, CALLS = C1 and C2, differ only by the calls (the model and the states are
the same), so (count(C2) − count(C1)) / (C2 − C1) is the count of one call, exactly.

Instructions executed inside libm (`sin`, `cos` in nalgebra's axis rotation, for a revolute
joint about a non-coordinate axis or a planar joint) are reported apart, per call, as the table
counts those `sin_cos` apart too; the other joint angles' sines and cosines are ours
(`spatial::sin_cos`) and counted as FLOPs.

Calibration (`--calibrate`, also run by the test): a length-64 dot product (64 m + 63 a) and a
nalgebra 3×3 matrix product (27 m + 18 a, which the compiler vectorises with packed
instructions) must be measured exactly.

Usage:
  benches/count_flops.py                       # default models and kernels, a table
  benches/count_flops.py --models arm,tree+floating --kernels rnea,crba
  benches/count_flops.py --json                # one JSON object per (model, kernel)
  benches/count_flops.py --calibrate
Needs valgrind and objdump; builds the harness with `cargo build --release --example
flop_harness` unless --no-build.
"""

import argparse
import collections
import concurrent.futures
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HARNESS = os.path.join(ROOT, "target", "release", "examples", "flop_harness")
# The same harness built without LLVM's vectorisers: every FLOP instruction is then one
# operation of the source, no lane computed in vain (see --scalar).
SCALAR_TARGET = os.path.join(ROOT, "target", "flops-scalar")
SCALAR_FLAGS = "-C llvm-args=-vectorize-slp=false -C llvm-args=-vectorize-loops=false"
KERNELS = ["rnea", "crba", "fd_aba", "fd_crba", "fd_rnea_columns", "gravity"]
# A fixed-base arm, the same floating, a branching tree with every joint kind (planar base,
# off-axis revolute, prismatic), a 12-link chain, a gripper with mimic joints.
MODELS = ["arm", "arm+floating", "src/core/tests/models/tree.urdf", "pendulum12", "gripper"]
CATEGORIES = ("mul", "add", "div", "sqrt")
# The building blocks the table prices (benches/flop_harness.rs `op:NAME`), each measured alone.
OPS = ["cross3", "mat3_vec3", "mat3_tr_vec3", "apply_motion", "apply_force",
       "inverse_apply_motion", "world_turn_axis", "world_slide_axis", "transpose_apply_force",
       "compose", "transpose_apply_inertia",
       "translate_inertia", "axis_turn_motion", "axis_turn_force", "axis_turn_inertia",
       "axis_turn_compose", "translate_compose",
       "inertia_apply", "cross_motion", "cross_force", "dot6", "add6", "inertia_add", "mat6_vec6",
       "subspace_column", "jcalc_revolute_z", "jcalc_revolute_axis", "jcalc_prismatic",
       "jcalc_planar", "jcalc_floating", "bias_planar"]

# mnemonic (without the AVX `v` prefix) -> category, for double precision.
SCALAR = {"addsd": "add", "subsd": "add", "mulsd": "mul", "divsd": "div", "sqrtsd": "sqrt"}
PACKED = {"addpd": "add", "subpd": "add", "mulpd": "mul", "divpd": "div", "sqrtpd": "sqrt",
          "haddpd": "add", "hsubpd": "add", "addsubpd": "add"}
X87 = {"fadd": "add", "faddp": "add", "fsub": "add", "fsubp": "add", "fsubr": "add",
       "fsubrp": "add", "fmul": "mul", "fmulp": "mul", "fdiv": "div", "fdivp": "div",
       "fdivr": "div", "fdivrp": "div", "fsqrt": "sqrt"}
FMA = re.compile(r"^vf(n?)m(add|sub)(132|213|231)(sd|pd|ss|ps)$")
SINGLE = re.compile(r"^v?(add|sub|mul|div|sqrt)(ss|ps)$")


def classify(mnemonic, operands):
    """{category: operations} for one execution of an instruction; {} if it does no FLOP."""
    lanes = 4 if "ymm" in operands else 2
    m = mnemonic[1:] if mnemonic.startswith("v") and mnemonic[1:] in SCALAR.keys() | PACKED.keys() else mnemonic
    if m in SCALAR:
        return {SCALAR[m]: 1}
    if m in PACKED:
        return {PACKED[m]: lanes}
    if m in X87:
        return {X87[m]: 1}
    fma = FMA.match(mnemonic)
    if fma:
        n = 1 if fma.group(4) in ("sd", "ss") else lanes
        return {"mul": n, "add": n}
    if SINGLE.match(mnemonic):
        # Single precision: none expected; counted so that it would show.
        return {"single": 1}
    return {}


_disassembly = {}


def flop_instructions(path):
    """{address: (mnemonic, {category: operations})} for the FLOP instructions of an ELF file."""
    if path not in _disassembly:
        out = subprocess.run(["objdump", "-d", "--no-show-raw-insn", path],
                             capture_output=True, text=True, check=True).stdout
        table = {}
        for line in out.splitlines():
            # "   4a2f0:\tmulsd  %xmm1,%xmm0"
            parts = line.split("\t")
            if len(parts) < 2 or not parts[0].strip().endswith(":"):
                continue
            try:
                address = int(parts[0].strip()[:-1], 16)
            except ValueError:
                continue
            fields = parts[1].split(None, 1)
            if not fields:
                continue
            ops = classify(fields[0], fields[1] if len(fields) > 1 else "")
            if ops:
                table[address] = (fields[0], ops)
        _disassembly[path] = table
    return _disassembly[path]


def parse_callgrind(path, lines=None):
    """{object: {address: executions}} from a callgrind file written with --dump-instr=yes,
    --compress-pos=no, --compress-strings=no; if `lines` is a dict, also
    lines[(object, address)] = "file:line" of the source the instruction came from."""
    counts = collections.defaultdict(lambda: collections.Counter())
    obj = None
    skip_next = False
    source = base = "?"
    with open(path) as f:
        for line in f:
            if line.startswith("ob="):
                obj = line[3:].strip()
            elif line.startswith("fl="):
                source = base = line[3:].strip()
            elif line.startswith(("fi=", "fe=")):
                source = line[3:].strip()
            elif line.startswith("fn="):
                source = base
            elif line.startswith("calls="):
                skip_next = True  # the next cost line is the call's inclusive cost
            elif line.startswith("0x"):
                if skip_next:
                    skip_next = False
                    continue
                fields = line.split()
                counts[obj][int(fields[0], 16)] += int(fields[2])
                if lines is not None:
                    lines[(obj, int(fields[0], 16))] = f"{source}:{fields[1]}"
    return counts


def build(scalar):
    """Builds the harness (release); with `scalar`, without the vectorisers, in its own
    target directory. Returns the harness's path."""
    command = ["cargo", "build", "--release", "--quiet", "--example", "flop_harness"]
    env = dict(os.environ)
    if not scalar:
        subprocess.run(command, cwd=ROOT, check=True)
        return HARNESS
    env["RUSTFLAGS"] = (env.get("RUSTFLAGS", "") + " " + SCALAR_FLAGS).strip()
    env["CARGO_TARGET_DIR"] = SCALAR_TARGET
    subprocess.run(command + ["--no-default-features"], cwd=ROOT, check=True, env=env)
    return os.path.join(SCALAR_TARGET, "release", "examples", "flop_harness")


def run_harness(model, kernel, calls, harness=HARNESS):
    """(flops by object and category, the table's count as printed by the harness)."""
    with tempfile.TemporaryDirectory() as tmp:
        out_file = os.path.join(tmp, "callgrind.out")
        proc = subprocess.run(
            ["valgrind", "--tool=callgrind", "--dump-instr=yes", "--compress-pos=no",
             "--compress-strings=no", f"--callgrind-out-file={out_file}",
             harness, model, kernel, str(calls)],
            capture_output=True, text=True, cwd=ROOT)
        if proc.returncode != 0:
            raise RuntimeError(f"{model} {kernel}: {proc.stderr.strip()[-2000:]}")
        table = json.loads(proc.stdout.strip().splitlines()[-1])
        counts = parse_callgrind(out_file)
    flops = {}
    for obj, executed in counts.items():
        if not os.path.isfile(obj):
            continue
        instrs = flop_instructions(obj)
        per_category = collections.Counter()
        for address, n in executed.items():
            mnemonic, ops = instrs.get(address, ("", {}))
            for category, k in ops.items():
                per_category[category] += n * k
            if ops:
                per_category["#" + mnemonic] += n
        if per_category:
            flops[os.path.basename(obj)] = per_category
    return flops, table


def measure(model, kernel, harness=HARNESS, c1=8, c2=24):
    """One call's FLOPs: ours (the harness and library code) and libm's, and the table's."""
    f1, table = run_harness(model, kernel, c1, harness)
    f2, _ = run_harness(model, kernel, c2, harness)
    ours = collections.Counter()
    libm = collections.Counter()
    for obj in set(f1) | set(f2):
        target = libm if obj.startswith("libm") else ours
        for category in set(f1.get(obj, {})) | set(f2.get(obj, {})):
            diff = f2.get(obj, {}).get(category, 0) - f1.get(obj, {}).get(category, 0)
            target[category] += diff / (c2 - c1)
    instructions = {k[1:]: v for k, v in sorted(ours.items()) if k.startswith("#") and v}
    return {
        "model": model,
        "kernel": kernel,
        "nv": table.get("nv"),
        "table": {c: table[c] for c in CATEGORIES} | {"sincos": table["sincos"]},
        "measured": {c: ours.get(c, 0) for c in CATEGORIES}
        | ({"single": ours["single"]} if ours.get("single") else {}),
        "libm": {c: libm.get(c, 0) for c in CATEGORIES},
        # Executions per call of each FLOP instruction (packed ones do 2 operations).
        "instructions": instructions,
    }


def total(counts):
    return sum(counts.get(c, 0) for c in CATEGORIES)


def calibrate(harness=HARNESS):
    """The calibration kernels' exact counts, measured; raises if any differs."""
    results = []
    for kernel in ("dot64", "mat3"):
        r = measure("-", kernel, harness)
        results.append(r)
        if any(r["measured"][c] != r["table"][c] for c in CATEGORIES):
            raise RuntimeError(f"calibration {kernel}: expected {r['table']}, measured {r['measured']}")
    return results


def fmt(counts):
    return "{:g} ({:g}m {:g}a {:g}d {:g}s)".format(
        total(counts), *(counts.get(c, 0) for c in CATEGORIES))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", default=",".join(MODELS))
    parser.add_argument("--kernels", default=",".join(KERNELS))
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    parser.add_argument("--calibrate", action="store_true", help="only the calibration")
    parser.add_argument("--ops", default=",".join(OPS),
                        help="building blocks measured alone ('' for none)")
    parser.add_argument("--no-build", action="store_true")
    parser.add_argument("--scalar", action="store_true",
                        help="measure a build without the vectorisers (its own target directory)")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    if args.no_build:
        harness = os.path.join(SCALAR_TARGET, "release", "examples", "flop_harness") \
            if args.scalar else HARNESS
    else:
        harness = build(args.scalar)
    for r in calibrate(harness):
        if not args.json:
            print(f"calibration {r['kernel']}: expected {fmt(r['table'])}, measured {fmt(r['measured'])}")
    if args.calibrate:
        return
    jobs = [("-", "op:" + o) for o in args.ops.split(",") if o]
    jobs += [(m, k) for m in args.models.split(",") if m for k in args.kernels.split(",") if k]
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda mk: measure_or_none(*mk, harness), jobs))
    if not args.json:
        print(f"{'model':<24} {'kernel':<16} {'table':>32} {'measured':>32} {'diff':>7} "
              f"{'libm/call':>10}")
    for r in results:
        if r is None:
            continue
        if args.json:
            print(json.dumps(r))
            continue
        t, m = total(r["table"]), total(r["measured"])
        print(f"{r['model']:<24} {r['kernel']:<16} {fmt(r['table']):>32} {fmt(r['measured']):>32} "
              f"{100 * (t - m) / m if m else 0:>+6.1f}% {total(r['libm']):>10g}")


def measure_or_none(model, kernel, harness):
    """None where the kernel has no count (ABA on a model with mimic joints)."""
    try:
        return measure(model, kernel, harness)
    except RuntimeError as e:
        if "no FLOP count" in str(e):
            return None
        raise


if __name__ == "__main__":
    sys.exit(main())
