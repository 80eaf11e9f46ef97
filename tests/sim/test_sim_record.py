"""The simulator's record of its poses: what is written is read back in order, a truncated tail
(a simulator killed mid-write) costs only the unfinished entry, and the topic names."""

from __future__ import annotations

from pathlib import Path

from grader.sim.record import DECLARE, MAGIC, PoseRecord, is_record_topic, read_record, record_topic


def test_written_entries_are_read_back_in_order(tmp_path: Path) -> None:
    path = tmp_path / "poses.record"
    rec = PoseRecord(path)
    rec.declare("/grader/sim_record/turtle1/pose")
    for i in range(5):
        rec.write("/grader/sim_record/turtle1/pose", bytes([i]) * 24, t_ns=1_000 + i)
    rec.close()
    got = list(read_record(path))
    assert got[0] == ("/grader/sim_record/turtle1/pose", DECLARE, b"")
    assert [(t, d) for _, t, d in got[1:]] == [(1_000 + i, bytes([i]) * 24) for i in range(5)]
    assert rec.count == 5


def test_a_truncated_tail_loses_only_the_unfinished_entry(tmp_path: Path) -> None:
    path = tmp_path / "poses.record"
    rec = PoseRecord(path)
    for i in range(3):
        rec.write("/grader/sim_record/turtle1/pose", b"x" * 40, t_ns=i)
    rec.close()
    data = path.read_bytes()
    path.write_bytes(data[:-10])
    assert [t for _, t, _ in read_record(path)] == [0, 1]


def test_no_record_reads_as_nothing(tmp_path: Path) -> None:
    assert list(read_record(tmp_path / "missing")) == []
    (tmp_path / "other").write_bytes(b"not a record" + MAGIC)
    assert list(read_record(tmp_path / "other")) == []


def test_record_topics() -> None:
    assert record_topic("/turtle1/pose") == "/grader/sim_record/turtle1/pose"
    assert is_record_topic(record_topic("turtle2/pose"))
    assert not is_record_topic("/grader/sim/turtle1/pose") and not is_record_topic("/grader/sim_recording")
