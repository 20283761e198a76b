"""How many simulated robots run in real time on this machine: N node processes in simulate mode
(sim_dt 1 ms, publish_rate 1000 Hz), each in its own namespace /robotK and ROS_DOMAIN_ID, for
--duration seconds; a run passes when no node reports a missed step on /diagnostics ("missed
steps": steps of a publish tick that ran more than 10 periods and 20 ms after it was due, so
simulated time the robot did not live in real time) over the measured window. N doubles from 1 until a run fails
(or --max-robots), then bisects; prints the largest passing N and, per N run, the missed steps,
the late publish ticks (ticks more than two periods after the one before: the scheduling jitter
the nodes saw, caught up within the 20 ms), the CPU per robot (utime + stime over wall time,
from /proc/PID/stat) and the worst real-time factor.

Run by launch_scripts/bench_many_robots.sh inside launch_scripts/netns_exec.sh (loopback only).
"""

import argparse
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
    procs = []
    for k in range(n):
        env = dict(os.environ, ROS_DOMAIN_ID=str(FIRST_DOMAIN + k))
        log = open(log_dir / f"robot{k}.log", "w")
        procs.append(subprocess.Popen(
            [args.bin, "node", "--ros-args", "-r", f"__ns:=/robot{k}",
             "-p", "mode:=simulate", "-p", f"sim_dt:={args.sim_dt}",
             "-p", f"publish_rate:={args.rate}", "-p", f"integrator:={args.integrator}",
             *[arg for parameter in args.parameters for arg in ("-p", parameter)]],
            env=env, stdout=log, stderr=subprocess.STDOUT))
    monitors = [Monitor(FIRST_DOMAIN + k) for k in range(n)]
    try:
        time.sleep(args.warmup)
        exited = [k for k, p in enumerate(procs) if p.poll() is not None]
        if exited:
            log = (log_dir / f"robot{exited[0]}.log").read_text(errors="replace").strip()
            sys.exit(f"many_robots: node {exited[0]} exited with {procs[exited[0]].returncode}: {log}")
        start = [m.fresh(10.0) for m in monitors]
        if any(s is None for s in start) or any(p.poll() is not None for p in procs):
            sys.exit(f"many_robots: with {n} robots a node did not report (logs in {log_dir})")
        t0, cpu0 = time.monotonic(), [cpu_seconds(p.pid) for p in procs]
        time.sleep(args.duration)
        end = [m.fresh(10.0) for m in monitors]
        wall = time.monotonic() - t0
        cpu = [(cpu_seconds(p.pid) - c) / wall for p, c in zip(procs, cpu0)]
    finally:
        for m in monitors:
            m.close()
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(10)
    if any(e is None for e in end):
        return False, sum(cpu) / n, 0.0, -1, -1

    def rise(key):
        return sum(int(e[key]) - int(s[key]) for s, e in zip(start, end))

    late, missed = rise("late publish ticks"), rise("missed steps")
    rtf = min(float(e["real-time factor"]) for e in end)
    return missed == 0, sum(cpu) / n, rtf, late, missed


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
    p.add_argument("parameters", nargs="*", metavar="NAME:=VALUE",
                   help="node parameters for every robot, e.g. urdf_file:=FILE")
    args = p.parse_args()
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
