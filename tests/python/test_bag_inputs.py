"""`spatial_dynamics replay` over the bags rosbag2 and its tools leave behind, against Pinocchio.

Bags are written with ``rosbags`` (its Writer does rosbag2's zstd ``file`` and ``message``
compression modes, both storages) and then, where a recorder would have left them so, changed
here: an MCAP cut short (a killed recorder), a split bag whose last file is cut (two bags'
files put in one directory under one metadata.yaml), a type named the Dashing way
(``sensor_msgs/JointState``), an sqlite3 bag without metadata.yaml. Every joint state that is
in the bag (for a cut file: in a record that is complete before the cut, found by walking the
MCAP records here) must be answered on /spatial_dynamics/gravity_effort with
``pin.computeGeneralizedGravity(q)``.

Damaged bags (hundreds of seeded byte changes and cuts of a small bag) must give exit code 0
or 1 with a message, never a panic (101) or a signal (≥ 128).
"""

import os
import random
import shutil
import subprocess

import numpy as np
import pinocchio as pin
import pytest
import io

import lz4.frame
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from ruamel.yaml import YAML
from test_replay import BIN, JS, NODE, TS, URDF, Pin, close, make_inputs, read_output, replay

try:
    from compression import zstd  # Python 3.14
except ImportError:
    from backports import zstd

JS_MSGDEF = TS.generate_msgdef(JS)[0]
JS_RIHS01 = TS.hash_rihs01(JS)
YAML_SAFE = YAML(typ="safe")


def load_yaml(path):
    return YAML_SAFE.load(path.read_text())


def dump_yaml(data, path):
    text = io.StringIO()
    YAML_SAFE.dump(data, text)
    path.write_text(text.getvalue())


def write(path, storage, records, mode=None, type_name=JS):
    """A bag by rosbags; `mode` is rosbag2's compression mode (file, message) with zstd."""
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    writer = Writer(path, version=9, storage_plugin=plugin)
    if mode is not None:
        writer.set_compression(mode, CompressionFormat.ZSTD)
    with writer:
        conns = {}
        for topic, _, log, data in sorted(records, key=lambda r: r[2]):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, type_name, msgdef=JS_MSGDEF, rihs01=JS_RIHS01)
            writer.write(conns[topic], log, data)


def check_gravity(out, states):
    """Every joint state in `states` answered, in order, with Pinocchio's gravity."""
    ref = Pin(URDF.read_text())
    gravity = read_output(out).get(NODE + "/gravity_effort", [])
    assert [g[0] for g in gravity] == [s["log"] for s in states]
    for s, (_, g, _) in zip(states, gravity):
        q = ref.q(dict(zip([f"joint{k}" for k in range(1, 8)], s["q"])))
        assert list(g.name) == s["names"]
        assert close(g.effort, ref.named(pin.computeGeneralizedGravity(ref.model, ref.data, q), s["names"]), 1e-9)


def files_of(bag):
    return sorted(p.name for p in bag.iterdir())


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("mode", [CompressionMode.FILE, CompressionMode.MESSAGE], ids=["file", "message"])
def test_zstd_compressed_bags(tmp_path, storage, mode):
    records, exp = make_inputs(n=900, commands=False)
    bag = tmp_path / "bag"
    write(bag, storage, records, mode=mode)
    meta = load_yaml(bag / "metadata.yaml")["rosbag2_bagfile_information"]
    assert meta["compression_mode"] == mode.name.lower() and meta["compression_format"] == "zstd"
    if mode == CompressionMode.FILE:
        assert all(f.endswith(".zstd") for f in meta["relative_file_paths"]), meta
    before = files_of(bag)
    summary, _ = replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm")
    assert summary["read"]["/joint_states"] == len(exp["states"]) + sum(exp["bad"].values())
    check_gravity(tmp_path / "out.mcap", exp["states"])
    # Nothing written beside the bag (no decompressed copy, no -wal/-shm).
    assert files_of(bag) == before


def records(buf, at, end):
    """(opcode, start, end, body) of the MCAP records from byte `at`, each whole before `end`:
    opcode u8, length u64, body."""
    while at + 9 <= end:
        op, n = buf[at], int.from_bytes(buf[at + 1 : at + 9], "little")
        if at + 9 + n > end:
            return
        yield op, at, at + 9 + n, buf[at + 9 : at + 9 + n]
        at += 9 + n


CHUNK_HEAD = 40  # start, end, uncompressed size, crc, compression length; then the name


def chunk_fields(body):
    """(compression, offset of the records, their length) of a chunk record's body."""
    cl = int.from_bytes(body[28:32], "little")
    rl = int.from_bytes(body[32 + cl : 40 + cl], "little")
    return body[32 : 32 + cl].decode(), CHUNK_HEAD + cl, rl


def decode(comp, data, whole=True):
    """A chunk's records; not `whole`: a streaming decoder fed the bytes that exist, which gives
    the blocks complete in them (Python's zstd and lz4 bindings)."""
    if comp == "zstd":
        return zstd.decompress(data) if whole else zstd.ZstdDecompressor().decompress(data)
    if comp == "lz4":
        return lz4.frame.decompress(data) if whole else lz4.frame.LZ4FrameDecompressor().decompress(data)
    assert comp == "", comp
    return data


def mcap_walk(data, cut):
    """(topic, log time) of every message in file order that is whole before byte `cut`, up to
    the data end record, and whether the walk met the data end. A plain reading of the MCAP
    record layout: top-level records that end by the cut; in a chunk the cut falls in (as `mcap
    recover` reads it), the records whole in what its bytes before the cut decode to."""
    topics, out = {}, []

    def handle(op, body):
        if op == 0x04:  # channel: id, schema id, topic
            tl = int.from_bytes(body[4:8], "little")
            topics[int.from_bytes(body[0:2], "little")] = body[8 : 8 + tl].decode()
        elif op == 0x05:  # message: channel, sequence, log time
            out.append((topics[int.from_bytes(body[0:2], "little")], int.from_bytes(body[6:14], "little")))

    def chunk(body, whole):
        comp, at, n = chunk_fields(body)
        inner = decode(comp, body[at : at + n], whole)
        for iop, _, _, ibody in records(inner, 0, len(inner)):
            handle(iop, ibody)

    for op, start, end, body in records(data, 8, len(data)):
        if end > cut:
            present = body[: max(cut - start - 9, 0)]
            if op == 0x06 and len(present) >= CHUNK_HEAD and len(present) >= chunk_fields(body)[1]:
                chunk(present, whole=False)
            return out, False
        if op == 0x0F:
            return out, True
        if op == 0x06:
            chunk(body, whole=True)
        else:
            handle(op, body)
    return out, False


def chunk_starts(data):
    """Byte offsets of the top-level chunk records of a whole MCAP file."""
    at, out = 8, []
    while at + 9 <= len(data) and data[at] != 0x0F:
        if data[at] == 0x06:
            out.append(at)
        at += 9 + int.from_bytes(data[at + 1 : at + 9], "little")
    return out


def storage_file(bag):
    (f,) = [p for p in bag.iterdir() if p.suffix in (".mcap", ".db3")]
    return f


def cut_bag(tmp_path, records):
    """An MCAP bag of `records` in `tmp_path/bag` whose file is cut at 60 % of its length, as a
    killed recorder leaves it: (bag, file, cut, the complete messages, whether it ended)."""
    bag = tmp_path / "bag"
    write(bag, "mcap", records)
    f = storage_file(bag)
    data = f.read_bytes()
    cut = int(len(data) * 0.6)
    f.write_bytes(data[:cut])
    complete, ended = mcap_walk(data, cut)
    return bag, f, cut, complete, ended


def test_cut_mcap_replays_every_complete_message(tmp_path):
    # rosbags closes a chunk past 1 MiB (rosbag2's writer at 768 KiB): several chunks.
    records, exp = make_inputs(n=9000, commands=True)
    bag, f, cut, complete, ended = cut_bag(tmp_path, records)
    assert not ended and complete
    logs = {t for topic, t in complete if topic == "/joint_states"}
    states = [s for s in exp["states"] if s["log"] in logs]
    assert 0 < len(states) < len(exp["states"])
    # The bag directory (metadata.yaml lists the cut file) and the file alone.
    for source in (bag, f):
        out = tmp_path / "out.mcap"
        summary, stderr = replay(source, out, "--builtin", "default_arm")
        assert summary["read"]["/joint_states"] == len(logs), stderr
        check_gravity(out, states)
        last = complete[-1][1]
        assert "warning" in stderr and str(f) in stderr and f"ends at byte {cut}" in stderr, stderr
        assert f"log time {last // 10**9}.{last % 10**9:09d} s" in stderr, stderr


def recompress_chunk(data, comp):
    """The file `data` up to the end of its first chunk, that chunk's records compressed with
    `comp` (zstd, lz4 frames of 64 KiB blocks, or none): (the bytes, where the chunk starts,
    where its records start)."""
    (start, body) = next((at, body) for op, at, _, body in records(data, 8, len(data)) if op == 0x06)
    old, at, n = chunk_fields(body)
    assert old == ""
    plain = body[at : at + n]
    packed = {"": plain, "zstd": zstd.compress(plain), "lz4": lz4.frame.compress(plain)}[comp]
    name = comp.encode()
    new = body[:28] + len(name).to_bytes(4, "little") + name + len(packed).to_bytes(8, "little") + packed
    record = b"\x06" + len(new).to_bytes(8, "little") + new
    return data[:start] + record, start, start + 9 + CHUNK_HEAD + len(name)


@pytest.mark.parametrize("comp", ["", "zstd", "lz4"], ids=["none", "zstd", "lz4"])
def test_cut_inside_the_one_chunk_replays_its_complete_records(tmp_path, comp):
    """A short recording is one chunk (rosbags closes a chunk past 1 MiB), so a cut falls inside
    it: the messages whole in what its bytes before the cut decode to (for
    zstd and lz4, the compressed blocks complete before the cut) are replayed, with a warning
    naming the byte, the messages recovered from the chunk and the last log time."""
    records_, exp = make_inputs(n=2500, commands=False)
    bag = tmp_path / "bag"
    write(bag, "mcap", records_)
    data, chunk, first = recompress_chunk(storage_file(bag).read_bytes(), comp)
    assert len(chunk_starts(data)) == 1
    cut = first + int((len(data) - first) * 0.6)
    f = tmp_path / "cut.mcap"
    f.write_bytes(data[:cut])
    complete, ended = mcap_walk(data, cut)
    assert not ended
    logs = {t for topic, t in complete if topic == "/joint_states"}
    states = [s for s in exp["states"] if s["log"] in logs]
    assert 0 < len(states) < len(exp["states"])
    out = tmp_path / "out.mcap"
    summary, stderr = replay(f, out, "--builtin", "default_arm")
    assert summary["read"]["/joint_states"] == len(logs), stderr
    check_gravity(out, states)
    last = complete[-1][1]
    assert f"ends at byte {cut} inside the chunk at byte {chunk}" in stderr, stderr
    assert f"recovered {len(complete)} messages" in stderr and "CRC unchecked" in stderr, stderr
    assert f"log time {last // 10**9}.{last % 10**9:09d} s" in stderr, stderr


@pytest.mark.parametrize("given", ["joint_states", "/joint_states"])
def test_cut_mcap_topic_recorded_without_a_leading_slash(tmp_path, given):
    """A cut file alone has no summary, so topics are only met while reading: `joint_states` as
    recorded (rosbags drops the slash) is still the topic asked for with or without it."""
    records, exp = make_inputs(n=9000, commands=False)
    records = [("joint_states",) + r[1:] for r in records]
    _, f, _, complete, _ = cut_bag(tmp_path, records)
    logs = {t for topic, t in complete if topic == "joint_states"}
    assert 0 < len(logs) < len(exp["states"])
    out = tmp_path / "out.mcap"
    summary, stderr = replay(f, out, "--builtin", "default_arm", "--joint-states", given)
    assert sum(summary["read"].get(k, 0) for k in ("joint_states", "/joint_states")) == len(logs), stderr
    check_gravity(out, [s for s in exp["states"] if s["log"] in logs])


def test_split_bag_with_a_cut_last_file(tmp_path):
    records, exp = make_inputs(n=8000, commands=False)
    records.sort(key=lambda r: r[2])
    half = len(records) // 2
    parts = []
    for k, part in enumerate((records[:half], records[half:])):
        b = tmp_path / f"part{k}"
        write(b, "mcap", part)
        parts.append(b)
    bag = tmp_path / "split"
    bag.mkdir()
    meta = load_yaml(parts[0] / "metadata.yaml")
    files = []
    for k, b in enumerate(parts):
        name = f"split_{k}.mcap"
        shutil.copy(storage_file(b), bag / name)
        files.append(name)
    meta["rosbag2_bagfile_information"]["relative_file_paths"] = files
    meta["rosbag2_bagfile_information"]["files"] = []
    dump_yaml(meta, bag / "metadata.yaml")
    last = bag / files[1]
    data = last.read_bytes()
    cut = chunk_starts(data)[-1] + 100  # inside its last chunk
    last.write_bytes(data[:cut])
    first_logs = {t for _, _, t, _ in records[:half]}
    complete, _ = mcap_walk(data, cut)
    logs = first_logs | {t for topic, t in complete if topic == "/joint_states"}
    states = [s for s in exp["states"] if s["log"] in logs]
    assert len([s for s in exp["states"] if s["log"] in first_logs]) < len(states) < len(exp["states"])
    summary, stderr = replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm")
    check_gravity(tmp_path / "out.mcap", states)
    assert f"split_1.mcap: the file ends at byte {cut}" in stderr, stderr


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_dashing_type_names(tmp_path, storage):
    records, exp = make_inputs(n=400, commands=True)
    bag = tmp_path / "bag"
    write(bag, storage, records, type_name="sensor_msgs/JointState")
    assert "sensor_msgs/JointState" in (bag / "metadata.yaml").read_text()
    summary, _ = replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm")
    assert summary["read"][NODE + "/effort_command"] > 0
    check_gravity(tmp_path / "out.mcap", exp["states"])


def test_sqlite3_without_metadata(tmp_path):
    records, exp = make_inputs(n=700, commands=False)
    bag = tmp_path / "bag"
    write(bag, "sqlite3", records)
    (bag / "metadata.yaml").unlink()
    before = files_of(bag)
    summary, stderr = replay(bag, tmp_path / "out.mcap", "--builtin", "default_arm")
    assert "no metadata.yaml" in stderr
    check_gravity(tmp_path / "out.mcap", exp["states"])
    assert files_of(bag) == before


def test_damaged_bags_never_crash(tmp_path):
    """Seeded byte changes, overwritten lengths and cuts of a small bag of each storage: every
    run ends with exit code 0 or 1, and a failure says why (never a panic or a signal)."""
    rng = random.Random(20)
    records, _ = make_inputs(n=40, commands=True)
    runs = 0
    for storage, count in (("mcap", 260), ("sqlite3", 60)):
        bag = tmp_path / storage
        write(bag, storage, records)
        good = storage_file(bag).read_bytes()
        bad = tmp_path / f"bad.{'mcap' if storage == 'mcap' else 'db3'}"
        for k in range(count):
            data = bytearray(good)
            kind = k % 4
            if kind == 0:
                data[rng.randrange(len(data))] = rng.randrange(256)
            elif kind == 1:
                i = rng.randrange(len(data) - 8)
                data[i : i + 8] = rng.getrandbits(64).to_bytes(8, "little")
            elif kind == 2:
                del data[rng.randrange(8, len(data)) :]
            else:
                for _ in range(8):
                    data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
            bad.write_bytes(data)
            run = subprocess.run(
                [BIN, "replay", "--bag", str(bad), "--out", str(tmp_path / "o.mcap"), "--builtin", "default_arm"],
                capture_output=True,
                text=True,
                timeout=60,
            )
            runs += 1
            assert run.returncode in (0, 1) and "panicked" not in run.stderr, (storage, k, run.returncode, run.stderr)
            # Exit 1 is an error naming the file, or a bag whose damage left no joint state to
            # answer (a topic or type name changed), which replay reports with its counts.
            if run.returncode == 1:
                named = str(bad) in run.stderr or "bad." in run.stderr
                assert named or "no joint state was answered" in run.stderr, run.stderr
    assert runs == 320
