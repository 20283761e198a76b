"""How many simulated robots run in real time on this machine: N node processes in simulate mode
(sim_dt 1 ms, publish_rate 1000 Hz), each in its own namespace /robotK and ROS_DOMAIN_ID, for
--duration seconds; a run passes when no node reports a missed step on /diagnostics ("missed
steps": steps of a publish tick that ran more than 10 periods and 20 ms after it was due, so
simulated time the robot did not live in real time) over the measured window. N doubles from 1
until a run fails (or --max-robots), then bisects; prints the largest passing N and, per N run, the missed steps,
the late publish ticks (ticks more than two periods after the one before: the scheduling jitter
the nodes saw, caught up within the 20 ms), the CPU per robot (utime + stime over wall time,
from /proc/PID/stat) and the worst real-time factor.

Run by launch_scripts/bench_many_robots.sh inside launch_scripts/netns_exec.sh (loopback only).
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

FIRST_DOMAIN = 11


def cpu_seconds(pid):
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Monitor:
    """The latest /diagnostics values of one node, in its domain."""

    def __init__(self, domain):
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node(f"many_robots_monitor_{domain}", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.values, self.reports = None, 0
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.arrived, 10)

    def arrived(self, msg):
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if "missed steps" in values:
                self.values, self.reports = values, self.reports + 1

    def fresh(self, timeout):
        """Values from a report that arrives after now (None after `timeout` s)."""
        seen, end = self.reports, time.monotonic() + timeout
        while self.reports <= seen and time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)
        return dict(self.values) if self.reports > seen else None

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def run(n, args, log_dir):
    """N nodes for the warm-up then the measured window:
    (passed, CPU per robot, worst RTF, late ticks, missed steps)."""
    procs, logs, monitors = [], [], []

    def exited():
        """Stops the benchmark with the log of a node that has exited (a refused parameter, a
        model it cannot load, a crash)."""
        for k, p in enumerate(procs):
            if p.poll() is not None:
                logs[k].flush()
                log = (log_dir / f"robot{k}.log").read_text(errors="replace").strip()
                sys.exit(f"many_robots: node {k} exited with {p.returncode}: {' '.join(p.args)}\n{log}")

    try:
        for k in range(n):
            env = dict(os.environ, ROS_DOMAIN_ID=str(FIRST_DOMAIN + k))
            logs.append(open(log_dir / f"robot{k}.log", "w"))
            procs.append(subprocess.Popen(
                [args.bin, "node", "--ros-args", "-r", f"__ns:=/robot{k}",
                 "-p", "mode:=simulate", "-p", f"sim_dt:={args.sim_dt}",
                 "-p", f"publish_rate:={args.rate}", "-p", f"integrator:={args.integrator}",
                 *[arg for parameter in args.parameters for arg in ("-p", parameter)]],
                env=env, stdout=logs[k], stderr=subprocess.STDOUT))
        # A node refuses its arguments, or a model it cannot load, within a moment of starting.
        time.sleep(min(args.warmup, 1.0))
        exited()
        monitors = [Monitor(FIRST_DOMAIN + k) for k in range(n)]
        time.sleep(max(0.0, args.warmup - 1.0))
        exited()
        start = [m.fresh(10.0) for m in monitors]
        exited()
        if any(s is None for s in start):
            sys.exit(f"many_robots: with {n} robots a node did not report (logs in {log_dir})")
        t0, cpu0 = time.monotonic(), [cpu_seconds(p.pid) for p in procs]
        time.sleep(args.duration)
        end = [m.fresh(10.0) for m in monitors]
        wall = time.monotonic() - t0
        exited()
        cpu = [(cpu_seconds(p.pid) - c) / wall for p, c in zip(procs, cpu0)]
    finally:
        for m in monitors:
            m.close()
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            p.wait(10)
        for log in logs:
            log.close()
    if any(e is None for e in end):
        return False, sum(cpu) / n, 0.0, -1, -1

    def rise(key):
        return sum(int(e[key]) - int(s[key]) for s, e in zip(start, end))

    late, missed = rise("late publish ticks"), rise("missed steps")
    rtf = min(float(e["real-time factor"]) for e in end)
    return missed == 0, sum(cpu) / n, rtf, late, missed


def model_parameters(args, parser):
    """The node parameters (NAME:=VALUE, values in YAML) for the model options given."""
    out = []
    if args.builtin is not None:
        args.urdf = Path(__file__).resolve().parent.parent / "config" / "models" / f"{args.builtin}.urdf"
        if "/" in args.builtin or not args.urdf.is_file():
            parser.error(f"--builtin {args.builtin}: the node loads a URDF, and config/models/ has none of that name")
    if args.urdf is not None:
        urdf = Path(args.urdf).resolve()
        if not urdf.is_file():
            parser.error(f"--urdf {args.urdf}: no such file")
        out.append(f"urdf_file:={json.dumps(str(urdf))}")
    if args.floating_base:
        out.append("floating_base:=true")
    if args.ignore_mimic:
        out.append("ignore_mimic:=true")
    if args.lock:
        out.append(f"locked_joints:={json.dumps(args.lock)}")
    if args.root is not None:
        out.append(f"root_link:={json.dumps(args.root)}")
    if args.tip:
        out.append(f"tip_links:={json.dumps(args.tip)}")
    if args.prune_massless:
        out.append("prune_massless:=true")
    if args.gravity is not None:
        try:
            gravity = [float(x) for x in args.gravity.split(",")]
        except ValueError:
            gravity = []
        if len(gravity) != 3:
            parser.error(f"--gravity {args.gravity}: not X,Y,Z")
        out.append(f"gravity:={json.dumps(gravity)}")
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bin", required=True)
    p.add_argument("--duration", type=float, default=10.0)
    p.add_argument("--warmup", type=float, default=3.0)
    p.add_argument("--max-robots", type=int, default=64)
    p.add_argument("--rate", type=float, default=1000.0)
    p.add_argument("--sim-dt", type=float, default=0.001)
    p.add_argument("--integrator", default="rk4")
    p.add_argument("--log-dir", default="target/bench-many-robots")
    model = p.add_argument_group("the model, as `spatial_dynamics model` takes it (given to the node as parameters)")
    source = model.add_mutually_exclusive_group()
    source.add_argument("--urdf", metavar="FILE", help="URDF file (urdf_file)")
    source.add_argument("--builtin", metavar="NAME", help="a built-in model with a file in config/models/ "
                        "(default_arm, particle, lamp, mimic_gripper; urdf_file)")
    model.add_argument("--floating-base", action="store_true", help="floating_base: true")
    model.add_argument("--ignore-mimic", action="store_true", help="ignore_mimic: true")
    model.add_argument("--lock", action="append", default=[], metavar="NAME=VALUE", help="locked_joints (repeatable)")
    model.add_argument("--root", metavar="LINK", help="root_link")
    model.add_argument("--tip", action="append", default=[], metavar="LINK", help="tip_links (repeatable)")
    model.add_argument("--prune-massless", action="store_true", help="prune_massless: true")
    model.add_argument("--gravity", metavar="X,Y,Z", help="gravity")
    p.add_argument("parameters", nargs="*", metavar="NAME:=VALUE",
                   help="more node parameters for every robot (docs/node.md), e.g. method:=crba")
    args = p.parse_intermixed_args()
    for parameter in args.parameters:
        if ":=" not in parameter:
            p.error(f"{parameter!r} is neither a model option nor a node parameter NAME:=VALUE")
    args.parameters = model_parameters(args, p) + args.parameters
    log_dir = Path(args.log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)

    results = {}

    def trial(n):
        results[n] = run(n, args, log_dir)
        ok, cpu, rtf, late, missed = results[n]
        print(f"== {n} robots: {'pass' if ok else 'FAIL'}, missed steps {missed}, late ticks {late}, "
              f"CPU per robot {cpu * 100:.1f} %, worst real-time factor {rtf:.3f}", file=sys.stderr)
        return ok

    good, bad, n = 0, None, 1
    while n <= args.max_robots:
        if not trial(n):
            bad = n
            break
        good, n = n, n * 2
    if bad is None and good < args.max_robots:
        bad = args.max_robots + 1
    while bad is not None and bad - good > 1:
        mid = (good + bad) // 2
        if trial(mid):
            good = mid
        else:
            bad = mid

    print("| robots | missed steps | late publish ticks | CPU per robot (% of a core) "
          "| worst real-time factor |")
    print("|---:|---:|---:|---:|---:|")
    for n in sorted(results):
        ok, cpu, rtf, late, missed = results[n]
        print(f"| {n} | {missed} | {late} | {cpu * 100:.1f} | {rtf:.3f} |")
    print()
    print(f"Largest N without a missed step over {args.duration:g} s: {good} "
          f"({args.integrator}, sim_dt {args.sim_dt:g} s, publish_rate {args.rate:g} Hz, "
          f"{os.cpu_count()} CPUs).")


if __name__ == "__main__":
    main()
