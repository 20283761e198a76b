"""The Python package against Pinocchio's Python bindings on UR5, measured in one run:

- one call: ``m.rnea(q, v, a)`` against ``pin.rnea(model, data, q, v, a)`` (the best of
  ``--repeat`` timings of ``--number`` calls each, per call);
- a batch: ``m.rnea(Q, V, A)`` on N states (2-D arrays, every core, the GIL released) against a
  Python loop calling ``pin.rnea`` on each row (timed on ``--loop-states`` of them, per state).

Prints a Markdown table with the ratios (Pinocchio's time over ours: above 1 is faster). Goals
(issue 28): the single call no slower than Pinocchio's (ratio >= 1), the batch at least 10x
faster per state than the loop. Run with the venv that setup_python_env.sh makes:

    .venv/bin/python benches/python_bindings.py [--states 100000]

On a loaded machine the numbers are indicative only; measure on an idle one.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import time
import timeit
from pathlib import Path

import numpy as np
import pinocchio as pin

import spatial_dynamics as sd


def ur5_urdf() -> Path:
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
    from pinocchio_cases import robots_dir

    return robots_dir() / "ur_description" / "urdf" / "ur5_robot.urdf"


def best_per_call(call, number: int, repeat: int) -> float:
    return min(timeit.repeat(call, number=number, repeat=repeat)) / number


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--states", type=int, default=100_000, help="states in the batch")
    parser.add_argument("--loop-states", type=int, default=20_000, help="states the pin.rnea loop is timed on")
    parser.add_argument("--number", type=int, default=20_000, help="single calls per timing")
    parser.add_argument("--repeat", type=int, default=7, help="timings (the best is kept)")
    args = parser.parse_args()

    path = ur5_urdf()
    ours = sd.Model.from_urdf(str(path))
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    # UR5's joints are revolute in both, in the same order: q, v and a are the same arrays.
    assert ours.v_names == [model.names[j] for j in range(1, model.njoints)], ours.v_names
    rng = np.random.default_rng(28)
    q, v, a = rng.uniform(-1.0, 1.0, (3, model.nv))
    assert np.allclose(ours.rnea(q, v, a), pin.rnea(model, data, q, v, a), rtol=1e-9, atol=1e-9)

    single_ours = best_per_call(lambda: ours.rnea(q, v, a), args.number, args.repeat)
    single_pin = best_per_call(lambda: pin.rnea(model, data, q, v, a), args.number, args.repeat)

    qs, vs, as_ = rng.uniform(-1.0, 1.0, (3, args.states, model.nv))
    batch, cpu = [], []
    for _ in range(args.repeat):
        used = resource.getrusage(resource.RUSAGE_SELF)
        start = time.perf_counter()
        ours.rnea(qs, vs, as_)
        batch.append((time.perf_counter() - start) / args.states)
        after = resource.getrusage(resource.RUSAGE_SELF)
        cpu.append((after.ru_utime - used.ru_utime + after.ru_stime - used.ru_stime) / args.states)
    batch_ours = min(batch)
    n = min(args.loop_states, args.states)

    def loop():
        for i in range(n):
            pin.rnea(model, data, qs[i], vs[i], as_[i])

    loop_pin = best_per_call(loop, 1, max(1, args.repeat // 2)) / n

    print(f"UR5 (nv = {model.nv}), {cpu_model()}, {os.cpu_count()} logical CPUs, "
          f"pin {pin.__version__}, numpy {np.__version__}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print()
    print("| what | spatial_dynamics (µs/state) | Pinocchio (µs/state) | ratio (pin / ours) |")
    print("|---|---|---|---|")
    print(f"| one call: `m.rnea(q, v, a)` vs `pin.rnea(model, data, q, v, a)` | {single_ours * 1e6:.3f} "
          f"| {single_pin * 1e6:.3f} | {single_pin / single_ours:.2f} |")
    print(f"| batch of {args.states}: `m.rnea(Q, V, A)` vs a Python loop over `pin.rnea` | "
          f"{batch_ours * 1e6:.3f} | {loop_pin * 1e6:.3f} | {loop_pin / batch_ours:.1f} |")
    print()
    print(f"The batch's CPU time per state, all threads together: {min(cpu) * 1e6:.3f} µs "
          f"(wall time × threads on an idle machine).")


if __name__ == "__main__":
    main()
