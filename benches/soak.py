"""Soak benchmark of the node over DDS (not a test): joint_states at 1 kHz and 10 kHz for 60 s each
while several clients call ~/inverse_dynamics, ~/forward_dynamics and ~/mass_matrix at once.

Reports, per phase: inputs sent, received by the node and dropped (the node's own counters on
/diagnostics), outputs published by the node and received here, input → output latency
(p50 / p99 / max, each output matched to its input by header stamp), service round trips and
failures, the node's CPU use, and its resident memory (VmRSS from /proc/PID/status) at start and
end (flat = no growth), plus the machine's load average (the 2 cores are shared).

The load comes from separate processes so that one Python interpreter is not the bottleneck:
a feeder (pre-serialised JointState, stamp patched in place, paced on CLOCK_MONOTONIC), one
receiver per output topic (rclpy EventsExecutor, raw messages: only the stamp is parsed), and N
service clients. All clocks are CLOCK_MONOTONIC of this machine, so send and arrival times of
different processes compare directly.

Run inside a private network namespace: launch_scripts/bench_soak.sh [--quick] [--rates 1000 10000]
[--duration 60] [--clients 3] [--service-rate 100] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
NAMES = [f"joint{i}" for i in range(1, 8)]
NODE = "/spatial_dynamics"
OUTPUTS = (f"{NODE}/gravity_effort", f"{NODE}/acceleration")
SERVICES = ("inverse_dynamics", "forward_dynamics", "mass_matrix")
# The output receivers' reader depth: 2 s at 5 kHz, 1 s at 10 kHz. On a loaded 2-core machine the
# receivers (Python) fall behind by more than 0.2 s at times.
RECEIVER_DEPTH = 10000
STAMP = struct.Struct("<iI")  # header.stamp (sec, nanosec) right after the 4-byte CDR encapsulation


def stop_on_signal():
    """A flag set by SIGINT or SIGTERM (the orchestrator stops its helpers with SIGINT)."""
    flag = {"stop": False}

    def handler(*_):
        flag["stop"] = True

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return flag


def ready():
    print("ready", flush=True)


# ---------------------------------------------------------------------------------------------
# Helper processes
# ---------------------------------------------------------------------------------------------


def run_feeder(args):
    """Publishes `rate × duration` joint_states, stamp (phase, sequence), and saves send times."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    rclpy.init()
    node = rclpy.create_node("soak_feeder")
    pub = node.create_publisher(JointState, "/joint_states", QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    rng = np.random.default_rng(7)
    templates = []
    for _ in range(16):
        msg = JointState(name=NAMES, position=rng.uniform(-2, 2, 7).tolist(), velocity=rng.uniform(-1, 1, 7).tolist())
        templates.append(bytearray(serialize_message(msg)))
    end = time.monotonic() + 10
    while pub.get_subscription_count() == 0 and time.monotonic() < end:
        time.sleep(0.02)
    time.sleep(0.5)
    n = int(args.rate * args.duration)
    period = 1e9 / args.rate
    sent = np.zeros(n, dtype=np.int64)
    flag = stop_on_signal()
    ready()
    t0 = time.monotonic_ns() + 1_000_000
    count = 0
    for k in range(n):
        if flag["stop"]:
            break
        target = t0 + int(k * period)
        while True:
            left = target - time.monotonic_ns()
            if left <= 0:
                break
            if left > 300_000:
                time.sleep((left - 200_000) * 1e-9)
        buf = templates[k % 16]
        STAMP.pack_into(buf, 4, args.phase, k)
        sent[k] = time.monotonic_ns()
        pub.publish(bytes(buf))
        count += 1
    took = (time.monotonic_ns() - t0) / 1e9
    np.save(args.out, sent[:count])
    print(json.dumps({"sent": count, "seconds": took}), flush=True)
    node.destroy_node()
    rclpy.shutdown()


def run_receiver(args):
    """Records the arrival time of every output message on one topic, by input sequence."""
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from spatial_dynamics_msgs.msg import JointDynamics

    rclpy.init()
    node = rclpy.create_node("soak_receiver_" + args.topic.rsplit("/", 1)[-1])
    arrivals = np.full(args.capacity, -1, dtype=np.int64)
    state = {"count": 0, "foreign": 0}

    def received(raw):
        now = time.monotonic_ns()
        sec, seq = STAMP.unpack_from(raw, 4)
        state["count"] += 1
        if sec == args.phase and seq < args.capacity:
            arrivals[seq] = now
        else:
            state["foreign"] += 1

    cls = JointDynamics if args.topic.endswith("acceleration") else JointState
    # A keep-last reader drops its oldest unread sample when full, so its depth is how far
    # this Python process may fall behind the node before an output the node sent counts as
    # lost (RECEIVER_DEPTH).
    node.create_subscription(cls, args.topic, received,
                             QoSProfile(depth=RECEIVER_DEPTH, reliability=ReliabilityPolicy.RELIABLE), raw=True)
    executor = EventsExecutor()
    executor.add_node(node)
    end = time.monotonic() + 10
    while not node.count_publishers(args.topic) and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
    flag = stop_on_signal()
    ready()
    while not flag["stop"]:
        executor.spin_once(timeout_sec=0.05)
    np.save(args.out, arrivals)
    print(json.dumps(state), flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


def run_client(args):
    """Calls the three services in turn at `service_rate` Hz; saves round trips and failures."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from spatial_dynamics_msgs.srv import ForwardDynamics, InverseDynamics, MassMatrix

    rclpy.init()
    node = rclpy.create_node(f"soak_client_{args.index}")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    kinds = {"inverse_dynamics": InverseDynamics, "forward_dynamics": ForwardDynamics, "mass_matrix": MassMatrix}
    clients = {name: node.create_client(srv, f"{NODE}/{name}") for name, srv in kinds.items()}
    end = time.monotonic() + 10
    while not all(c.service_is_ready() for c in clients.values()) and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
    rng = np.random.default_rng(args.index)

    def request(name):
        q, v, x = (rng.uniform(-1, 1, 7).tolist() for _ in range(3))
        if name == "inverse_dynamics":
            return InverseDynamics.Request(name=NAMES, position=q, velocity=v, acceleration=x)
        if name == "forward_dynamics":
            return ForwardDynamics.Request(name=NAMES, position=q, velocity=v, effort=x)
        return MassMatrix.Request(name=NAMES, position=q)

    def call(name, timeout):
        future = clients[name].call_async(request(name))
        deadline = time.monotonic() + timeout
        while not future.done() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.005)
        if not future.done():
            clients[name].remove_pending_request(future)
            return None
        return future.result()

    for name in SERVICES:  # one untimed call per service before the measured phases
        call(name, 3.0)
    flag = stop_on_signal()
    ready()
    started = time.monotonic()
    results = {name: {"rtt_ns": [], "timeouts": 0, "failed": 0, "messages": []} for name in SERVICES}
    period = 1.0 / args.service_rate
    next_call = time.monotonic()
    k = 0
    while not flag["stop"]:
        name = SERVICES[k % 3]
        k += 1
        t0 = time.monotonic_ns()
        response = call(name, 1.0)
        r = results[name]
        if response is None:
            r["timeouts"] += 1
        else:
            r["rtt_ns"].append(time.monotonic_ns() - t0)
            if not response.success:
                r["failed"] += 1
                if len(r["messages"]) < 3:
                    r["messages"].append(response.message)
        next_call += period
        while not flag["stop"] and time.monotonic() < next_call:
            executor.spin_once(timeout_sec=max(0.0, min(0.01, next_call - time.monotonic())))
        if time.monotonic() > next_call + 1.0:
            next_call = time.monotonic()
    for r in results.values():
        r["seconds"] = time.monotonic() - started
    Path(args.out).write_text(json.dumps(results))
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


# ---------------------------------------------------------------------------------------------
# The orchestrator
# ---------------------------------------------------------------------------------------------


def rss_kib(pid):
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return -1


def cpu_seconds(pid):
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def udp_drops(pid):
    """Datagrams the kernel dropped on the node's UDP sockets (receive buffer full), summed over them.

    /proc/net/udp{,6} list every socket of this network namespace with its inode and a drop count;
    the node's sockets are the inodes among its open file descriptors."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    total = 0
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            f = line.split()
            if len(f) >= 13 and f[9] in inodes:
                total += int(f[12])
    return total


def loadavg():
    return float(Path("/proc/loadavg").read_text().split()[0])


def spawn(role, *options):
    return subprocess.Popen([sys.executable, __file__, "--role", role, *map(str, options)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def wait_ready(proc, what, timeout=30.0):
    end = time.monotonic() + timeout
    lines = []
    while time.monotonic() < end:
        line = proc.stdout.readline()
        if not line:
            break
        if line.strip() == "ready":
            return
        lines.append(line)
    raise RuntimeError(f"{what} did not get ready:\n{''.join(lines)}")


class Diagnostics:
    """The node's latest /diagnostics values, and RSS samples, gathered while spinning."""

    def __init__(self, pid):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor

        rclpy.init()
        self.rclpy = rclpy
        self.node = rclpy.create_node("soak_monitor")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.values = None
        self.reports = 0
        self.pid = pid
        self.rss = []  # (monotonic s, KiB)
        self.compute = []  # (mean µs, max µs) of each report with computations
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.arrived, 10)

    def arrived(self, msg):
        for status in msg.status:
            if status.name == f"{NODE.lstrip('/')}: dynamics":  # diagnostic_updater: no leading slash
                self.values = {kv.key: kv.value for kv in status.values}
                self.reports += 1
                if "compute mean (us)" in self.values:
                    self.compute.append((float(self.values["compute mean (us)"]), float(self.values["compute max (us)"])))

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.1, max(0.0, end - time.monotonic())))
            if not self.rss or time.monotonic() - self.rss[-1][0] >= 0.5:
                self.rss.append((time.monotonic(), rss_kib(self.pid)))

    def fresh(self, timeout=5.0):
        """Counters from a report that arrived after now."""
        seen = self.reports
        end = time.monotonic() + timeout
        while self.reports < seen + 1 and time.monotonic() < end:
            self.spin_for(0.05)
        return dict(self.values or {})

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.shutdown()


def counter(values, key):
    return int(values.get(key, 0))


def drops(values):
    return {k: int(v) for k, v in values.items() if " dropped: " in k}


def stats_us(samples_ns):
    if len(samples_ns) == 0:
        return {"p50": None, "p99": None, "max": None}
    a = np.asarray(samples_ns, dtype=float) / 1e3
    return {"p50": float(np.percentile(a, 50)), "p99": float(np.percentile(a, 99)), "max": float(a.max())}


def phase(diag, node_pid, index, rate, duration, args, workdir):
    receivers = {}
    capacity = int(rate * duration) + 10
    for topic in OUTPUTS:
        out = workdir / f"arrivals_{index}_{topic.rsplit('/', 1)[-1]}.npy"
        receivers[topic] = (spawn("receiver", "--topic", topic, "--phase", index, "--capacity", capacity, "--out", out), out)
    clients = []
    for i in range(args.clients):
        out = workdir / f"client_{index}_{i}.json"
        clients.append((spawn("client", "--index", i, "--service-rate", args.service_rate, "--out", out), out))
    for topic, (proc, _) in receivers.items():
        wait_ready(proc, f"receiver {topic}")
    for i, (proc, _) in enumerate(clients):
        wait_ready(proc, f"client {i}")
    feeder_out = workdir / f"sent_{index}.npy"
    before = diag.fresh()
    computed_from = len(diag.compute)
    cpu0, rss0, load0, t0 = cpu_seconds(node_pid), rss_kib(node_pid), loadavg(), time.monotonic()
    kernel0 = udp_drops(node_pid)
    feeder = spawn("feeder", "--rate", rate, "--duration", duration, "--phase", index, "--out", feeder_out)
    wait_ready(feeder, "feeder")
    while feeder.poll() is None:
        diag.spin_for(0.2)
    feeder_report = json.loads(feeder.stdout.read().strip().splitlines()[-1])
    fed_until = time.monotonic()
    diag.spin_for(1.0)  # let the last outputs arrive
    wall = time.monotonic() - t0
    cpu1, load1 = cpu_seconds(node_pid), loadavg()
    for proc, _ in clients:
        proc.send_signal(signal.SIGINT)
    for topic, (proc, _) in receivers.items():
        proc.send_signal(signal.SIGINT)
    after = diag.fresh()
    rss1 = rss_kib(node_pid)
    kernel1 = udp_drops(node_pid)
    result = {
        "rate_hz": rate, "duration_s": duration,
        "feeder": {"sent": feeder_report["sent"], "achieved_hz": feeder_report["sent"] / max(feeder_report["seconds"], 1e-9)},
        "node": {
            "received": counter(after, "/joint_states received") - counter(before, "/joint_states received"),
            "dropped": {k: v - drops(before).get(k, 0) for k, v in drops(after).items() if v - drops(before).get(k, 0)},
            "published": {t: counter(after, f"{t} published") - counter(before, f"{t} published") for t in OUTPUTS},
            # datagrams (of any topic) the kernel dropped because the node's socket buffer was full
            "kernel_udp_drops": kernel1 - kernel0,
            "cpu_percent_of_one_core": 100.0 * (cpu1 - cpu0) / wall,
            # Per joint_states (and per ~/reference): the node's 1-s report means, their median, and the max.
            "compute_median_of_means_us": float(np.median([m for m, _ in diag.compute[computed_from:]])) if diag.compute[computed_from:] else None,
            "compute_max_us": max((x for _, x in diag.compute[computed_from:]), default=None),
        },
        # monotonic times (s) of the load's start and end: the RSS trace (top level) is cut with them
        "t_start": t0, "t_fed": fed_until,
        "rss_kib": {"start": rss0, "end": rss1, "max_while_fed": max((k for t, k in diag.rss if t0 <= t <= fed_until), default=rss0),
                    # growth while the load ran, over its second half (after the buffers filled)
                    "second_half_trend_kib_per_min": trend(diag.rss, fed_until - (fed_until - t0) / 2, fed_until)},
        "loadavg_1min": {"start": load0, "end": load1},
        "outputs": {}, "services": {},
    }
    sent = np.load(feeder_out)
    for topic, (proc, out) in receivers.items():
        proc.wait(20)
        report = json.loads(proc.stdout.read().strip().splitlines()[-1])
        arrivals = np.load(out)[: len(sent)]
        got = arrivals >= 0
        latency = arrivals[got] - sent[got]
        result["outputs"][topic] = {"received": int(got.sum()), "lost": int(len(sent) - got.sum()),
                                    "foreign": report["foreign"], "latency_us": stats_us(latency)}
    for i, (proc, out) in enumerate(clients):
        proc.wait(20)
        for name, r in json.loads(out.read_text()).items():
            agg = result["services"].setdefault(name, {"calls": 0, "timeouts": 0, "failed": 0, "rtt_ns": [], "messages": [],
                                                       "per_second": 0.0})
            agg["calls"] += len(r["rtt_ns"]) + r["timeouts"]
            agg["per_second"] += (len(r["rtt_ns"]) + r["timeouts"]) / max(r["seconds"], 1e-9)
            agg["timeouts"] += r["timeouts"]
            agg["failed"] += r["failed"]
            agg["rtt_ns"] += r["rtt_ns"]
            agg["messages"] += r["messages"]
    for name, agg in result["services"].items():
        agg["rtt_us"] = stats_us(agg.pop("rtt_ns"))
    return result


def trend(trace, start, end):
    """Least-squares slope (KiB/min) of the RSS samples taken between start and end."""
    pts = np.array([(t, k) for t, k in trace if start <= t <= end], dtype=float)
    if len(pts) < 3:
        return None
    return float(np.polyfit(pts[:, 0] - pts[0, 0], pts[:, 1], 1)[0]) * 60


def fmt(x, digits=0):
    return "–" if x is None else f"{x:.{digits}f}"


def print_report(results, rss_trace, start_rss, end_rss):
    print("\n## Soak: joint_states in, services called by several clients, 7-DOF default arm\n")
    print("| rate (Hz) | s | sent (achieved Hz) | node received | node dropped | kernel UDP drops | output | published | received | lost | latency p50 / p99 / max (µs) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        dropped = sum(r["node"]["dropped"].values())
        for j, topic in enumerate(OUTPUTS):
            o = r["outputs"][topic]
            lat = o["latency_us"]
            head = (f"| {r['rate_hz']:.0f} | {r['duration_s']:.0f} | {r['feeder']['sent']} ({r['feeder']['achieved_hz']:.0f}) "
                    f"| {r['node']['received']} | {dropped} | {r['node']['kernel_udp_drops']} ") if j == 0 else "| | | | | | "
            print(f"{head}| `{topic.rsplit('/', 1)[-1]}` | {r['node']['published'][topic]} | {o['received']} | {o['lost']} "
                  f"| {fmt(lat['p50'])} / {fmt(lat['p99'])} / {fmt(lat['max'])} |")
    print("\n| rate (Hz) | service | calls (per s) | timeouts | success=false | round trip p50 / p99 / max (µs) |")
    print("|---|---|---|---|---|---|")
    for r in results:
        for name, s in r["services"].items():
            lat = s["rtt_us"]
            print(f"| {r['rate_hz']:.0f} | `~/{name}` | {s['calls']} ({s['per_second']:.0f}) | {s['timeouts']} | {s['failed']} "
                  f"| {fmt(lat['p50'])} / {fmt(lat['p99'])} / {fmt(lat['max'])} |")
    print("\n| rate (Hz) | node CPU (% of a core) | compute per message: median of 1-s means / max (µs) | RSS start → max → end (KiB) | RSS trend, 2nd half (KiB/min) | load avg (1 min) start → end |")
    print("|---|---|---|---|---|---|")
    for r in results:
        n = r["node"]
        print(f"| {r['rate_hz']:.0f} | {n['cpu_percent_of_one_core']:.0f} | {fmt(n['compute_median_of_means_us'], 1)} / {fmt(n['compute_max_us'])} "
              f"| {r['rss_kib']['start']} → {r['rss_kib']['max_while_fed']} → {r['rss_kib']['end']} | {fmt(r['rss_kib']['second_half_trend_kib_per_min'], 1)} "
              f"| {r['loadavg_1min']['start']:.2f} → {r['loadavg_1min']['end']:.2f} |")
        if r["node"]["dropped"]:
            print(f"|   | node drops by reason: {r['node']['dropped']} | | | | |")
    rss = np.array([k for _, k in rss_trace], dtype=float)
    tt = np.array([t for t, _ in rss_trace], dtype=float)
    slope = float(np.polyfit(tt - tt[0], rss, 1)[0]) * 60 if len(rss) > 2 else float("nan")
    print(f"\nNode RSS: {start_rss} KiB at start (after warm-up), {end_rss} KiB at the end, max {int(rss.max())} KiB; "
          f"linear trend {slope:+.1f} KiB/min over {len(rss)} samples.")
    every = max(1, len(rss_trace) // 24)
    print("RSS over time (s: MiB): " + ", ".join(f"{t - tt[0]:.0f}: {k / 1024:.1f}" for t, k in rss_trace[::every]))
    for r in results:
        for name, s in r["services"].items():
            if s["messages"]:
                print(f"{r['rate_hz']:.0f} Hz ~/{name} failures: {s['messages']}")


def orchestrate(args):
    import tempfile

    binary = os.environ.get("SPATIAL_DYNAMICS_BIN", str(REPO / "target" / "release" / "spatial_dynamics"))
    workdir = Path(tempfile.mkdtemp(prefix="sd_soak_"))
    log = open(workdir / "node.log", "wb")
    node = subprocess.Popen([binary, "node"], stdout=log, stderr=subprocess.STDOUT)
    diag = None
    try:
        diag = Diagnostics(node.pid)
        if not diag.fresh(timeout=15.0):
            raise RuntimeError(f"no /diagnostics from the node (log: {workdir / 'node.log'})")
        diag.spin_for(1.0)
        start_rss = rss_kib(node.pid)
        results = []
        for index, rate in enumerate(args.rates, start=1):
            print(f"phase {index}: {rate:.0f} Hz for {args.duration:.0f} s, {args.clients} service clients at "
                  f"{args.service_rate:.0f} Hz each (load avg {loadavg():.2f})", file=sys.stderr, flush=True)
            results.append(phase(diag, node.pid, index, rate, args.duration, args, workdir))
            diag.spin_for(1.0)
        end_rss = rss_kib(node.pid)
        if node.poll() is not None:
            raise RuntimeError(f"the node died (log: {workdir / 'node.log'})")
        print_report(results, diag.rss, start_rss, end_rss)
        if args.json:
            Path(args.json).write_text(json.dumps({"phases": results, "rss_kib": {"start": start_rss, "end": end_rss,
                                                   "trace": diag.rss}}, indent=1))
        lost_1k = [sum(o["lost"] for o in r["outputs"].values()) + sum(r["node"]["dropped"].values())
                   for r in results if r["rate_hz"] <= 1000]
        return 0 if all(x == 0 for x in lost_1k) else 3
    finally:
        if diag is not None:
            diag.close()
        node.send_signal(signal.SIGINT)
        try:
            node.wait(5)
        except subprocess.TimeoutExpired:
            node.kill()
        log.close()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--role", choices=["orchestrator", "feeder", "receiver", "client"], default="orchestrator",
                   help=argparse.SUPPRESS)
    p.add_argument("--rates", type=float, nargs="+", default=[1000.0, 10000.0], help="joint_states rates, Hz (default 1000 10000)")
    p.add_argument("--duration", type=float, default=60.0, help="seconds per rate (default 60)")
    p.add_argument("--clients", type=int, default=3, help="service client processes (default 3)")
    p.add_argument("--service-rate", type=float, default=100.0, help="calls per second per client (default 100)")
    p.add_argument("--quick", action="store_true", help="short run for the test suite: 5 kHz for 8 s, 2 clients at 50 Hz")
    p.add_argument("--json", help="also write the results as JSON to this file")
    # helper-process options
    p.add_argument("--rate", type=float, help=argparse.SUPPRESS)
    p.add_argument("--phase", type=int, help=argparse.SUPPRESS)
    p.add_argument("--topic", help=argparse.SUPPRESS)
    p.add_argument("--capacity", type=int, help=argparse.SUPPRESS)
    p.add_argument("--index", type=int, help=argparse.SUPPRESS)
    p.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.role == "feeder":
        return run_feeder(args)
    if args.role == "receiver":
        return run_receiver(args)
    if args.role == "client":
        return run_client(args)
    if args.quick:
        args.rates, args.duration, args.clients, args.service_rate = [5000.0], 8.0, 2, 50.0
    return orchestrate(args)


if __name__ == "__main__":
    sys.exit(main())
