"""The simulator's own record of the poses it published, and the bag topic it ends up on.

Why: a grade on poses must rest on poses the simulator published, and no topic can prove that.
Any node of the graph can publish on ``/turtle1/pose``, and on the grader's copy
``/grader/sim/turtle1/pose`` too; rclpy 7.1.6 gives a subscriber no publisher identity per
message (its ``MessageInfo`` holds time stamps and sequence numbers only), so the recorder
cannot tell whose sample it took.

So the simulator also writes every pose it publishes to a file (``grader sim --pose-record
FILE``): the CDR bytes it handed to its publisher and the wall-clock time it did so. The file is
in the scenario's own folder, which the simulator (grader code, outside the sandbox) can write
and student code cannot reach at all (the sandbox shows it no output folder, see docs/sandbox.md, "Student
code runs in a sandbox"). When the scenario ends, the scenario process hands the record to its
recorder, which writes it into the bag under ``record_topic(pose_topic)``
(``/grader/sim_record/turtle1/pose``) and never records anything received over DDS under that
prefix. Every message on it was therefore published by the simulator, exactly as recorded, at the
time recorded: that is what makes it sound. Analyzers read poses from it
(:func:`grader.analyze._common.sim_pose`).

Format: the line ``MAGIC``, then per pose ``<q H I>`` (publish time in ns since the epoch, topic
length, data length), the topic (UTF-8) and the CDR data; an entry with time -1 and no data
declares a topic (a turtle's record exists from its spawn, so a bag whose record holds no pose
still says that the record was made, and nothing else is taken for it). A reader stops at a
truncated tail (a simulator killed mid-write loses at most its last unflushed poses).
"""

from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import BinaryIO, Iterator

MAGIC = b"grader-sim-record 1\n"
_HEAD = struct.Struct("<qHI")
#: bag topics under this prefix hold the simulator's record and nothing received over DDS
RECORD_PREFIX = "/grader/sim_record"
#: type of every topic of the record
POSE_TYPE = "turtlesim/msg/Pose"
#: the time of an entry that declares a topic
DECLARE = -1
#: seconds between flushes of the file (a SIGKILL loses at most this much of the record)
FLUSH_S = 0.5


def record_topic(pose_topic: str) -> str:
    """``/turtle1/pose`` -> ``/grader/sim_record/turtle1/pose``."""
    return RECORD_PREFIX + "/" + pose_topic.lstrip("/")


def is_record_topic(topic: str) -> bool:
    return topic.startswith(RECORD_PREFIX + "/")


class PoseRecord:
    """Appends ``(topic, cdr)`` pairs with the wall-clock time of the call."""

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        self._f: BinaryIO = open(self.path, "wb")
        self._f.write(MAGIC)
        self._flushed = time.monotonic()
        self.count = 0

    def declare(self, topic: str) -> None:
        """A topic of the record (written when its turtle is spawned, before any pose)."""
        name = topic.encode()
        self._f.write(_HEAD.pack(DECLARE, len(name), 0))
        self._f.write(name)

    def write(self, topic: str, data: bytes, t_ns: int | None = None) -> None:
        name = topic.encode()
        self._f.write(_HEAD.pack(time.time_ns() if t_ns is None else t_ns, len(name), len(data)))
        self._f.write(name)
        self._f.write(data)
        self.count += 1
        now = time.monotonic()
        if now - self._flushed >= FLUSH_S:
            self._f.flush()
            self._flushed = now

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()


def read_record(path: Path | str) -> Iterator[tuple[str, int, bytes]]:
    """``(topic, t_ns, cdr)`` of every complete entry of a record file, in order (none if it is
    missing or not a record); ``t_ns`` is ``DECLARE`` for a declaration."""
    try:
        buf = Path(path).read_bytes()
    except OSError:
        return
    if not buf.startswith(MAGIC):
        return
    i = len(MAGIC)
    while i + _HEAD.size <= len(buf):
        t_ns, n_topic, n_data = _HEAD.unpack_from(buf, i)
        end = i + _HEAD.size + n_topic + n_data
        if end > len(buf):
            return
        topic = buf[i + _HEAD.size:i + _HEAD.size + n_topic].decode(errors="replace")
        yield topic, t_ns, buf[i + _HEAD.size + n_topic:end]
        i = end
