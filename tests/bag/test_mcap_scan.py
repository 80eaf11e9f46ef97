"""MCAP writing (``mcap`` package) and our scanning: third-party readers agree with us; a
truncated file keeps every complete chunk, as ``mcap``'s own stream reader sees it."""

from __future__ import annotations

import re
import struct
import time
from collections import Counter
from pathlib import Path

import pytest

from grader.bag.mcap_scan import scan
from grader.bag.msgdefs import DefinitionSource
from grader.bag.reader import open_bag
from grader.bag.repair import repair_bag
from grader.bag.writer import BagWriter, open_mcap
from grader.errors import GraderError

from baghelpers import assert_jazzy_v9_metadata, crash

POSE = "turtlesim/msg/Pose"
T0 = 1_700_000_000_000_000_000


def pose(i: int) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<5f", i, -i, 0.5, 1.0, 0.25)


def write_pose_bag(path: Path, n: int, chunk_size: int = 4096, topics: int = 2) -> Path:
    src = DefinitionSource()
    with BagWriter(path, chunk_size=chunk_size) as w:
        for k in range(topics):
            w.add_topic(f"/t{k}", POSE, src.full_text(POSE), type_hash=src.type_hash(POSE),
                        offered_qos_profiles=[{"reliability": "reliable", "durability": "volatile"}])
        for i in range(n):
            for k in range(topics):
                w.write(f"/t{k}", T0 + i * 16_000_000 + k, pose(i), T0 + i * 16_000_000 - 5000, i)
    return path


def test_third_party_readers_agree_with_ours(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    bag = write_pose_bag(tmp_path / "b", 500)
    assert_jazzy_v9_metadata(bag)
    ours = open_bag(bag)
    assert ours.finalized and len(ours.scans[0].blocks) == 2 and ours.scans[0].chunk_count > 5
    with open(bag / "b_0.mcap", "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        mc = [(ch.topic, m.log_time, m.publish_time, m.sequence, m.data)
              for _, ch, m in reader.iter_messages(log_time_order=True)]
        stats = reader.get_summary().statistics
    assert stats.message_count == 1000 and stats.chunk_count == ours.scans[0].chunk_count
    with AnyReader([bag]) as r:
        rb = [(c.topic, t, bytes(raw)) for c, t, raw in r.messages()]
        decoded = [r.deserialize(raw, c.msgtype) for c, _, raw in r.messages()]
    mine = [(t, lt, pt, bytes(d)) for t, lt, pt, d in ours.iter_messages()]
    assert [(t, lt, d) for t, lt, _, _, d in mc] == [(t, lt, d) for t, lt, _, d in mine] == rb
    assert [pt for _, _, pt, _, _ in mc] == [pt for _, _, pt, _ in mine]
    assert [s for t, _, _, s, _ in mc if t == "/t0"] == list(range(500))
    assert decoded[-1].x == 499.0 and decoded[-1].y == -499.0


def _chunks(path: Path, n: int) -> tuple[list[int], list[int], list[int]]:
    """Write 5 chunks of n messages through the ``mcap`` Writer, flushing after each, and leave
    the file unfinished; return each chunk's start and end offsets and the running counts."""
    w, f = open_mcap(path, chunk_size=10**9)
    sid = w.register_schema(POSE, "ros2msg", b"float32 x\nfloat32 y\nfloat32 theta\n"
                            b"float32 linear_velocity\nfloat32 angular_velocity\n")
    cid = w.register_channel("/p", "cdr", sid, {"offered_qos_profiles": "[]\n", "topic_type_hash": ""})
    starts, ends, counts = [], [], []
    for c in range(5):
        starts.append(f.tell())
        for i in range(n):
            w.add_message(cid, T0 + (c * n + i) * 1000, pose(c * n + i), 0)
        w.flush()
        ends.append(f.tell())
        counts.append((c + 1) * n)
    f.close()
    return starts, ends, counts


def mcap_stream_count(path: Path) -> int:
    """Messages ``mcap``'s StreamReader yields before the file's cut (the library's view)."""
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    n = 0
    with open(path, "rb") as fh:
        try:
            for rec in StreamReader(fh).records:
                n += isinstance(rec, Message)
        except Exception:  # noqa: BLE001 - the cut ends the stream, whatever the library raises
            pass
    return n


def test_truncated_file_yields_every_complete_chunk(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    starts, ends, counts = _chunks(path, 40)
    data = path.read_bytes()
    # cut inside each chunk, inside each chunk's message index, and just after it
    for k in range(5):
        for cut, expect in ((starts[k] + 50, counts[k - 1] if k else 0),
                            (ends[k] - 5, counts[k]), (ends[k], counts[k])):
            (tmp_path / "cut.mcap").write_bytes(data[:cut])
            res = scan(tmp_path / "cut.mcap")
            got = res.message_count()
            assert got == expect, (k, cut, got, expect)
            assert not res.complete and res.problem
            xs = [struct.unpack_from("<f", bytes(b.buf), int(o) + 4)[0]
                  for blocks in res.blocks.values() for b in blocks for o in b.offsets]
            assert xs == [float(i) for i in range(expect)]
            assert mcap_stream_count(tmp_path / "cut.mcap") == expect


def test_repair_makes_crashed_bag_readable_by_rosbags(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader

    src = DefinitionSource()
    bag = tmp_path / "crash"
    w = BagWriter(bag, chunk_size=2048)
    w.add_topic("/p", POSE, src.full_text(POSE), type_hash=src.type_hash(POSE))
    for i in range(300):
        w.write("/p", T0 + i * 1000, pose(i))
        if i == 149:
            w.flush()       # what the recorder's timer does: the first 150 are on disk for sure
    crash(w)               # what SIGKILL leaves: the open chunk lost, no summary, no metadata.yaml
    mcap_file = bag / "crash_0.mcap"
    raw = mcap_file.read_bytes()
    mcap_file.write_bytes(raw[:-7])   # and half a record at the end
    before = open_bag(bag)
    assert not before.finalized and any("repair" in p for p in before.problems)
    n = before.message_count
    assert 150 <= n < 300
    assert n == mcap_stream_count(mcap_file)     # every complete chunk, as the library sees it
    with pytest.raises(Exception):  # noqa: B017 - whichever error rosbags raises on a crashed bag
        with AnyReader([bag]) as r:   # rosbags cannot read it yet
            list(r.messages())
    report = repair_bag(bag)
    assert report.messages == n and report.rewritten == ["crash_0.mcap"]
    assert (bag / "crash_0.mcap.damaged").is_file()
    assert_jazzy_v9_metadata(bag)
    with AnyReader([bag]) as r:
        xs = [r.deserialize(raw, c.msgtype).x for c, _, raw in r.messages()]
    assert xs == [float(i) for i in range(n)]
    assert repair_bag(bag).already_ok


def test_chunks_reach_disk_on_a_timer(tmp_path: Path) -> None:
    src = DefinitionSource()
    w = BagWriter(tmp_path / "t", chunk_size=10**9, chunk_age_s=0.05)
    w.add_topic("/p", POSE, src.full_text(POSE))
    mcap_file = tmp_path / "t" / "t_0.mcap"
    w.write("/p", T0, pose(1))
    size = mcap_file.stat().st_size
    w.poll()
    assert mcap_file.stat().st_size == size, "closed a fresh chunk early"
    assert scan(mcap_file).message_count() == 0
    time.sleep(0.08)
    w.poll()
    assert scan(mcap_file).message_count() == 1
    w.close()


@pytest.mark.parametrize("content,needle", [
    (b"", "not an MCAP file"), (b"hello world, not a bag", "not an MCAP file"),
])
def test_garbage_is_a_clear_error(tmp_path: Path, content: bytes, needle: str) -> None:
    bag = tmp_path / "g"
    bag.mkdir()
    (bag / "g_0.mcap").write_bytes(content)
    with pytest.raises(GraderError, match=needle):
        open_bag(bag)


def test_missing_and_empty_bags_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(GraderError, match="does not exist"):
        open_bag(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(GraderError, match="no .mcap file"):
        open_bag(tmp_path / "empty")
    (tmp_path / "db").mkdir()
    (tmp_path / "db" / "x.db3").write_bytes(b"")
    with pytest.raises(GraderError, match="SQLite3"):
        open_bag(tmp_path / "db")
    bag = write_pose_bag(tmp_path / "m", 10)
    (bag / "m_0.mcap").rename(bag / "other.mcap")
    with pytest.raises(GraderError, match="lists m_0.mcap, which is missing"):
        open_bag(bag)
    (bag / "other.mcap").rename(bag / "m_0.mcap")
    # a damaged metadata.yaml does not hide the data: it is reported, and repair rewrites it
    for text, needle in (("rosbag2_bagfile_information: [1, 2", "not valid YAML .*line 1.*repair"),
                         ("something: else\n", "rosbag2_bagfile_information")):
        (bag / "metadata.yaml").write_text(text)
        damaged = open_bag(bag)
        assert not damaged.finalized and damaged.message_count == 20
        assert re.search(needle, " ".join(damaged.problems)), damaged.problems
        assert not repair_bag(bag).already_ok
        assert open_bag(bag).finalized
        assert_jazzy_v9_metadata(bag)


def test_counts_per_topic(tmp_path: Path) -> None:
    bag = write_pose_bag(tmp_path / "c", 123, topics=3)
    counts = Counter(t for t, *_ in open_bag(bag).iter_messages())
    assert counts == {"/t0": 123, "/t1": 123, "/t2": 123}
