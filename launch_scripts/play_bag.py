"""Plays a rosbag2 bag (MCAP or sqlite3) into a running ROS 2 graph over DDS, like `ros2 bag play`
(which has no wheel): each topic gets an rclpy publisher of its own type, messages go out as their
recorded CDR bytes at the recorded pace (or `--rate` times it), and `/clock` can carry the bag's
time so that nodes with `use_sim_time` follow the replay.

Run it with launch_scripts/play_bag.sh (the repo's .venv, which has rclpy, rosbags and our
spatial_dynamics_msgs). Examples:

    launch_scripts/play_bag.sh BAG --clock 100                 # /clock at 100 Hz from bag time
    launch_scripts/play_bag.sh BAG --clock-topics joint_states # /clock = stamp of each joint_states
    launch_scripts/play_bag.sh BAG --rate 0.5 --loop --topics /joint_states --start-offset 2

Time: the bag time of a message is its recorded receive timestamp (as ros2 bag play uses it;
header stamps are not touched). Playback time starts at the bag's first message (plus
`--start-offset`) and advances with the wall clock times `--rate`; a message is published when
playback time reaches its bag time. `/clock` (rosgraph_msgs/Clock, rclcpp's ClockQoS: best
effort, depth 1) carries playback time `--clock HZ` times a second, and with `--clock-topics`
(or `--clock-topics-all`) also the bag time of each message on those topics just before it is
published. With `--loop` time jumps back to the start at each pass.
QoS: each publisher offers the QoS recorded in the bag for its topic (reliability, durability,
history depth), else reliable, volatile, keep last 100; `--qos-best-effort` forces best effort.
Interface types must be importable in this Python (`<pkg>.msg`); a topic whose type is not is
skipped with a warning.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import time
from collections import Counter
from pathlib import Path

NS = 1_000_000_000


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag", type=Path, help="rosbag2 directory (metadata.yaml and .mcap or .db3 files)")
    p.add_argument("--rate", type=float, default=1.0, help="playback speed factor (default 1: recorded speed)")
    p.add_argument("--clock", type=float, nargs="?", const=40.0, default=0.0, metavar="HZ",
                   help="publish /clock from bag time at HZ (40 if given without a value; default: no /clock)")
    p.add_argument("--clock-topics", nargs="+", default=[], metavar="TOPIC",
                   help="also publish /clock with the bag time of each message on these topics, just before it")
    p.add_argument("--clock-topics-all", action="store_true", help="--clock-topics for every topic played")
    p.add_argument("--topics", nargs="+", default=[], metavar="TOPIC", help="play only these topics (default: all)")
    p.add_argument("--start-offset", type=float, default=0.0, metavar="S", help="start S seconds into the bag")
    p.add_argument("--loop", action="store_true", help="play again from the start when the end is reached")
    p.add_argument("--remap", nargs="+", default=[], metavar="FROM:=TO", help="publish topic FROM (or /clock) as TO")
    p.add_argument("--delay", type=float, default=0.0, metavar="S", help="wait S seconds before playing")
    p.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="S",
                   help="before playing, wait up to S seconds until every topic played has a subscriber")
    p.add_argument("--qos-best-effort", action="store_true", help="offer best effort on every topic")
    p.add_argument("--node-name", default="play_bag", help="name of the rclpy node (default play_bag)")
    p.add_argument("--quiet", action="store_true", help="no summary at the end")
    args = p.parse_args(argv)
    if not args.rate > 0:
        p.error("--rate must be > 0")
    if args.clock < 0 or args.start_offset < 0 or args.delay < 0:
        p.error("--clock, --start-offset and --delay must be ≥ 0")
    for item in args.remap:
        if ":=" not in item:
            p.error(f"--remap {item}: expected FROM:=TO")
    return args


def normalise(topic: str) -> str:
    return topic if topic.startswith("/") else "/" + topic


def message_class(msgtype: str):
    """'sensor_msgs/msg/JointState' → the rclpy class (None if it cannot be imported)."""
    pkg, kind, name = msgtype.split("/")
    try:
        return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
    except (ImportError, AttributeError):
        return None


def qos_for(connections, best_effort: bool):
    """The publisher QoS: what the bag recorded for the topic (first profile), else reliable,
    volatile, keep last 100."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rosbags.interfaces import QosDurability, QosHistory, QosReliability

    reliability, durability, depth = ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE, 100
    for conn in connections:
        profiles = getattr(conn.ext, "offered_qos_profiles", None) or []
        if profiles:
            q = profiles[0]
            if q.reliability == QosReliability.BEST_EFFORT:
                reliability = ReliabilityPolicy.BEST_EFFORT
            if q.durability == QosDurability.TRANSIENT_LOCAL:
                durability = DurabilityPolicy.TRANSIENT_LOCAL
            if q.history == QosHistory.KEEP_LAST and q.depth > 0:
                depth = max(q.depth, 1)
            break
    if best_effort:
        reliability = ReliabilityPolicy.BEST_EFFORT
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability, durability=durability)


class Player:
    """Publishes a bag's messages at playback time; owns the rclpy node."""

    def __init__(self, args):
        import rclpy
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosbags.rosbag2 import Reader
        from rosgraph_msgs.msg import Clock

        self.args = args
        self.reader = Reader(args.bag)
        self.reader.open()
        rclpy.init()
        self.rclpy = rclpy
        self.node = rclpy.create_node(args.node_name)
        self.Clock = Clock
        wanted = {normalise(t) for t in args.topics}
        remap = {normalise(a): normalise(b) for a, b in (r.split(":=", 1) for r in args.remap)}
        by_topic = {}
        for conn in self.reader.connections:
            topic = normalise(conn.topic)
            if wanted and topic not in wanted:
                continue
            by_topic.setdefault(topic, []).append(conn)
        missing = wanted - set(by_topic)
        if missing:
            raise SystemExit(f"play_bag: no such topic in {args.bag}: {', '.join(sorted(missing))} "
                             f"(the bag has {', '.join(sorted(normalise(c.topic) for c in self.reader.connections))})")
        self.publishers = {}  # connection id -> (publisher, output topic, source topic)
        self.connections = []
        for topic, conns in sorted(by_topic.items()):
            types = {c.msgtype for c in conns}
            if len(types) > 1:
                print(f"play_bag: {topic} has several types {sorted(types)}: skipped", file=sys.stderr)
                continue
            cls = message_class(conns[0].msgtype)
            if cls is None:
                print(f"play_bag: {topic}: type {conns[0].msgtype} is not importable here: skipped", file=sys.stderr)
                continue
            out = remap.get(topic, topic)
            pub = self.node.create_publisher(cls, out, qos_for(conns, args.qos_best_effort))
            for c in conns:
                self.publishers[c.id] = (pub, out, topic)
                self.connections.append(c)
        if not self.connections:
            raise SystemExit("play_bag: nothing to play")
        clock_topics = {normalise(t) for t in args.clock_topics}
        self.clock_on = {c.id for c in self.connections if args.clock_topics_all or normalise(c.topic) in clock_topics}
        self.clock_pub = None
        if args.clock > 0 or self.clock_on:
            self.clock_pub = self.node.create_publisher(Clock, remap.get("/clock", "/clock"),
                                                        QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self.last_clock = None
        self._looped = False
        self.sent = Counter()
        self.stop = False

    def close(self):
        self.reader.close()
        self.node.destroy_node()
        self.rclpy.shutdown()

    def publish_clock(self, t_ns):
        if self.last_clock is not None and t_ns < self.last_clock and not self._looped:
            t_ns = self.last_clock  # periodic ticks never step back within a pass
        self._looped = False
        self.last_clock = t_ns
        self.clock_pub.publish(self.Clock(clock=_time(t_ns)))
        self.sent["/clock"] += 1

    def wait_subscribers(self, timeout):
        from rclpy.executors import SingleThreadedExecutor

        executor = SingleThreadedExecutor()
        executor.add_node(self.node)
        pubs = {id(p): p for p, _, _ in self.publishers.values()}.values()
        end = time.monotonic() + timeout
        while time.monotonic() < end and not all(p.get_subscription_count() > 0 for p in pubs):
            executor.spin_once(timeout_sec=0.05)
        lonely = sorted({out for p, out, _ in self.publishers.values() if p.get_subscription_count() == 0})
        if lonely:
            print(f"play_bag: no subscriber after {timeout} s on {', '.join(lonely)}; playing anyway", file=sys.stderr)
        executor.remove_node(self.node)

    def play_once(self):
        """One pass over the bag; returns False if stopped."""
        args = self.args
        start = self.reader.start_time + round(args.start_offset * NS)
        wall0 = time.monotonic()
        period = 1.0 / args.clock if args.clock > 0 else None
        next_tick = wall0
        self._looped = True

        def playback_ns(wall):
            return start + round((wall - wall0) * args.rate * NS)

        for conn, stamp, raw in self.reader.messages(connections=self.connections, start=start):
            due = wall0 + (stamp - start) / NS / args.rate
            while True:
                if self.stop:
                    return False
                now = time.monotonic()
                if period is not None and next_tick <= min(now, due):
                    self.publish_clock(playback_ns(next_tick))
                    next_tick += period
                    if next_tick < now - 1.0:  # far behind (suspended): do not burst
                        next_tick = now
                    continue
                wake = due if period is None else min(due, next_tick)
                if wake <= now:
                    break
                _sleep_until(wake)
            pub, _, topic = self.publishers[conn.id]
            if conn.id in self.clock_on:
                self.publish_clock(stamp)
            pub.publish(bytes(raw))
            self.sent[topic] += 1
        return True

    def run(self):
        if self.args.wait_for_subscribers > 0:
            self.wait_subscribers(self.args.wait_for_subscribers)
        if self.args.delay > 0:
            time.sleep(self.args.delay)
        started = time.monotonic()
        passes = 0
        while self.play_once():
            passes += 1
            if not self.args.loop:
                break
        if not self.args.quiet:
            took = time.monotonic() - started
            counts = ", ".join(f"{t}: {n}" for t, n in sorted(self.sent.items()))
            print(f"play_bag: {passes} pass(es) in {took:.3f} s; published {counts}", file=sys.stderr)


def _time(t_ns):
    from builtin_interfaces.msg import Time

    return Time(sec=t_ns // NS, nanosec=t_ns % NS)


def _sleep_until(deadline):
    """Sleeps until `deadline` (time.monotonic()); the last half millisecond is spun, so that
    messages go out on time at kHz rates."""
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return
        if left > 0.0015:
            time.sleep(left - 0.001)
        elif left > 0.0005:
            time.sleep(0)
        # else: spin


def main(argv=None):
    args = parse_args(argv)
    player = Player(args)

    def stop(*_):
        player.stop = True

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    try:
        player.run()
    finally:
        player.close()


if __name__ == "__main__":
    main()
