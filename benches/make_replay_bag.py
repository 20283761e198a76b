"""Writes a synthetic bag for benchmarking `spatial_dynamics replay` (launch_scripts/bench_replay.sh).

The embedded default arm (7 joints, names joint1..joint7) moves smoothly,
q_j(t) = A_j sin(w_j t + p_j), sampled at 1 kHz with +-0.2 ms jitter in the stamps; every
message carries positions, velocities and efforts (zeros). Every tenth joint state is followed
by an effort command on /spatial_dynamics/effort_command (100 Hz). A /robot_description message
comes first, so the replay needs no --urdf.

Messages are packed into a CDR template made once by rosbags (only stamps and numbers change),
so writing a million takes seconds, not minutes.

Usage: .venv/bin/python benches/make_replay_bag.py --out DIR [--messages N] [--storage mcap|sqlite3] [--zstd]
           [--zstd-mode file|message]
"""

import argparse
import shutil
import struct
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_typestore

REPO = Path(__file__).resolve().parents[1]
TS = get_typestore(Stores.ROS2_JAZZY)
JS = "sensor_msgs/msg/JointState"
JOINTS = [f"joint{k}" for k in range(1, 8)]


def template(names, sizes):
    """A serialized JointState and the byte offsets of its stamp and of each float array."""
    T, H, J = (TS.types[n] for n in ("builtin_interfaces/msg/Time", "std_msgs/msg/Header", JS))
    marks = [np.arange(n, dtype=float) + 1000.0 * (k + 1) + 0.125 for k, n in enumerate(sizes)]
    msg = J(
        header=H(stamp=T(sec=0x5EC0DE, nanosec=0x0A0B0C0D), frame_id="base"),
        name=names,
        position=marks[0],
        velocity=marks[1],
        effort=marks[2],
    )
    data = bytes(TS.serialize_cdr(msg, JS))
    stamp = data.index(struct.pack("<iI", 0x5EC0DE, 0x0A0B0C0D))
    arrays = [data.index(struct.pack("<d", m[0])) if len(m) else None for m in marks]
    return bytearray(data), stamp, arrays


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, type=Path, help="bag directory to (re)create")
    ap.add_argument("--messages", type=int, default=1_000_000, help="joint states (default 1e6)")
    ap.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap")
    ap.add_argument("--zstd", action="store_true", help="zstd-compressed MCAP chunks (as rosbag2's presets write)")
    ap.add_argument(
        "--zstd-mode",
        choices=["file", "message"],
        help="rosbag2's zstd compression mode: each storage file, or each message (either storage)",
    )
    args = ap.parse_args()

    if args.out.exists():
        shutil.rmtree(args.out)
    rng = np.random.default_rng(1)
    amp = np.array([0.5, 0.4, 0.6, 0.3, 0.5, 0.4, 1.0])
    omega = np.array([2.0, 3.0, 1.5, 2.5, 3.0, 2.0, 1.0])
    phase = np.array([0.1, 0.7, -0.3, 1.2, 0.0, -1.0, 2.0])
    t0 = 1_700_000_000_000_000_000
    stamps = t0 + np.arange(args.messages, dtype=np.int64) * 1_000_000 + rng.integers(-200_000, 200_000, args.messages)
    ts = (stamps - t0) * 1e-9
    s = np.outer(ts, omega) + phase
    q, v = amp * np.sin(s), amp * omega * np.cos(s)

    js, js_stamp, (js_q, js_v, js_e) = template(JOINTS, [7, 7, 7])
    struct.pack_into("<7d", js, js_e, *np.zeros(7))
    cmd, cmd_stamp, (_, _, cmd_e) = template(JOINTS, [0, 0, 7])
    tau = rng.normal(0, 5, (args.messages // 10 + 1, 7))

    plugin = StoragePlugin.MCAP if args.storage == "mcap" else StoragePlugin.SQLITE3
    writer = Writer(args.out, version=9, storage_plugin=plugin)
    if args.zstd:
        if args.storage != "mcap":
            ap.error("--zstd is for MCAP chunks")
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    if args.zstd_mode:
        if args.zstd:
            ap.error("--zstd and --zstd-mode are one compression each")
        writer.set_compression(CompressionMode[args.zstd_mode.upper()], CompressionFormat.ZSTD)
    with writer:
        c_desc = writer.add_connection("/robot_description", "std_msgs/msg/String", typestore=TS)
        c_js = writer.add_connection("/joint_states", JS, typestore=TS)
        c_cmd = writer.add_connection("/spatial_dynamics/effort_command", JS, typestore=TS)
        urdf = (REPO / "config" / "models" / "default_arm.urdf").read_text()
        String = TS.types["std_msgs/msg/String"]
        writer.write(c_desc, int(stamps[0]) - 1_000_000, bytes(TS.serialize_cdr(String(data=urdf), "std_msgs/msg/String")))
        for i in range(args.messages):
            t = int(stamps[i])
            struct.pack_into("<iI", js, js_stamp, t // 1_000_000_000, t % 1_000_000_000)
            struct.pack_into("<7d", js, js_q, *q[i])
            struct.pack_into("<7d", js, js_v, *v[i])
            log = t + 500_000
            writer.write(c_js, log, bytes(js))
            if i % 10 == 0:
                struct.pack_into("<iI", cmd, cmd_stamp, t // 1_000_000_000, t % 1_000_000_000)
                struct.pack_into("<7d", cmd, cmd_e, *tau[i // 10])
                writer.write(c_cmd, log + 10_000, bytes(cmd))
    print(f"wrote {args.out}: {args.messages} joint states, {args.messages // 10 + (args.messages % 10 > 0)} commands")


if __name__ == "__main__":
    main()
