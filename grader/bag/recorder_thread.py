"""The recorder as a thread of the calling process (the scenario process records its own graph).

The recorder process (``python -m grader.bag.recorder``) costs each scenario one more Python
start-up, ``import rclpy`` and first DDS participant, and the teardown of all of it: measured
with ``benchmarks/bench_cpu.py`` at ~0.35 s of CPU per scenario (start-up 0.04 s, imports 0.08 s,
``rclpy.init`` + first node 0.15-0.19 s, exit), while a second rclpy context in a process that
already has one costs ~0.01 s. So the scenario process runs the same :class:`Recorder` in a
thread, on a context of its own (its own participant and wait set: nothing is shared with the
driver's executor, and the driver's context can shut down first without cutting the bag short).

Receive times are unchanged by where the recorder runs: they are the DDS layer's
``received_timestamp`` of each sample, not the time Python got to it.

Two things only the scenario's recorder does (:class:`ScenarioRecorder`), so that nothing a
student node publishes can stand in for the grader's own records:

* *local* topics (the driver's ``/grader/events`` and ``/grader/stdout``): the driver hands their
  messages over in process (:meth:`RecorderThread.post`), stamped when it emitted them, and a
  node publishing on those names over DDS is not recorded: no student node can add an event (say,
  a service call of the grader's with the student's own client id);
* the simulator's own record of its poses (:mod:`grader.sim.record`), written from the
  simulator's file when the scenario ends (``stop(records=...)``), each pose at the time it was
  published.
"""

from __future__ import annotations

import queue
import threading
import time
from pathlib import Path
from typing import Sequence

from grader.bag.recorder import Recorder, _log, build_parser, recorder_argv
from grader.errors import GraderError
from grader.sim.record import DECLARE, POSE_TYPE, read_record


class ScenarioRecorder(Recorder):
    """The recorder with local topics and the simulator's record (see the module docstring)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        #: record files of the simulator to write into the bag before it is closed
        self.records: list[Path] = []
        #: topics written in process only (:meth:`add_local`), never taken from DDS
        self.local: set[str] = set()
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._posted = 0

    def wanted(self, topic: str) -> bool:
        return topic not in self.local and super().wanted(topic)

    def spin_once(self, timeout_s: float) -> int:
        return super().spin_once(timeout_s) + self._write_posted()

    def add_local(self, topic: str, type_name: str) -> None:
        """A topic whose messages come only from :meth:`post` (call before :meth:`run`)."""
        self.local.add(topic)
        self.writer.add_topic(topic, type_name, self.defs.full_text(type_name),
                              type_hash=self.defs.type_hash(type_name))

    def post(self, topic: str, data: bytes, t_ns: int | None = None) -> None:
        """A message of a local topic, from any thread (written by the recorder's own thread)."""
        self._inbox.put((topic, time.time_ns() if t_ns is None else t_ns, data))

    def _write_posted(self) -> int:
        n = 0
        while True:
            try:
                topic, t_ns, data = self._inbox.get_nowait()
            except queue.Empty:
                return n
            n += 1
            self._posted += 1
            self.writer.write(topic, t_ns, data, t_ns, self._posted)

    def write_record(self, path: Path) -> int:
        """Write the simulator's record of its poses (:mod:`grader.sim.record`) into the bag, each
        pose at the time the simulator published it; returns how many."""
        n = 0
        for topic, t_ns, data in read_record(path):
            if topic not in self.writer.topics:
                self.writer.add_topic(topic, POSE_TYPE, self.defs.full_text(POSE_TYPE),
                                      type_hash=self.defs.type_hash(POSE_TYPE))
            if t_ns == DECLARE:
                continue
            n += 1
            self.writer.write(topic, t_ns, data, t_ns, n)
        return n

    def finish(self) -> int:
        self._write_posted()
        for path in self.records:
            try:
                self.write_record(path)
            except Exception as exc:  # noqa: BLE001 - the bag is still finalized without it
                _log(f"could not write the simulator's record {path}: {type(exc).__name__}: {exc}")
        return super().finish()


class RecorderThread:
    """``start()`` returns once the first discovery round is done (like ``READY``);
    ``stop()`` drains, finalizes the bag and returns the number of messages written."""

    def __init__(self, out_dir: Path | str, topics: Sequence[str] | None = None, *, domain_id: int,
                 extra: Sequence[str] = (), local: Sequence[str] = ()) -> None:
        """``local``: ``std_msgs/msg/String`` topics this process writes itself (:meth:`post`);
        a node publishing on them over DDS is not recorded."""
        argv = recorder_argv(out_dir, topics, extra=extra)[3:]     # the CLI's options and defaults
        self.recorder = ScenarioRecorder(build_parser().parse_args(argv), domain_id=domain_id)
        for topic in local:
            self.recorder.add_local(topic, "std_msgs/msg/String")
        self._topics = None if topics is None else set(topics)
        self.ready = threading.Event()
        self.error: BaseException | None = None
        self.messages: int | None = None
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)

    @property
    def native_id(self) -> int | None:
        """The recording thread's kernel id (lockstep does not wait for its writing)."""
        return self._thread.native_id

    def _run(self) -> None:
        try:
            self.recorder.run(on_ready=self.ready.set)
            self.messages = self.recorder.writer.message_count
        except BaseException as exc:  # noqa: BLE001 - reported by start()/stop()
            self.error = exc
            try:
                self.recorder.writer.close()     # whatever happened, leave a readable bag
            except Exception:  # noqa: BLE001
                pass
        finally:
            self.ready.set()

    def start(self, timeout_s: float = 15.0) -> None:
        self._thread.start()
        if not self.ready.wait(timeout_s):
            raise GraderError(f"the recorder did not become ready within {timeout_s:.0f} s.")
        if self.error is not None:
            raise GraderError(f"the recorder stopped: {type(self.error).__name__}: {self.error}")

    def recorded(self, topic: str) -> int:
        """Messages written on ``topic`` so far (0 while the recorder has not subscribed to it or
        nothing has arrived): the proof that a publisher is being recorded, which a graph query
        cannot give (the subscription may exist before DDS has matched it with the publisher)."""
        entry = self.recorder.writer.topics.get(topic)
        return entry.info.message_count if entry is not None else 0

    def records(self, topic: str) -> bool:
        """Whether ``topic`` is one this recording takes (all topics, or it is in the list)."""
        return self._topics is None or topic in self._topics

    def matched(self, topic: str, publishers: int) -> bool:
        """The recorder's subscription on ``topic`` is matched with at least ``publishers``
        publishers: what is published from now on is recorded. A graph query alone cannot say it
        (the recorder is another DDS participant, which discovers a new publisher, subscribes and
        matches it up to ~1 s after the driver does on a loaded machine)."""
        sub = self.recorder.subs.get(topic)
        try:
            return sub is not None and sub.handle is not None and sub.handle.get_publisher_count() >= publishers
        except Exception:  # noqa: BLE001 - resubscribing in the recorder's thread just now
            return False

    def post(self, topic: str, data: bytes) -> None:
        """A serialized message of a ``local`` topic, stamped now (thread-safe)."""
        self.recorder.post(topic, data)

    def stop(self, timeout_s: float = 20.0, records: Sequence[Path] = ()) -> int | None:
        """``records``: the simulator's record files (:mod:`grader.sim.record`), written into the
        bag before it is finalized."""
        self.recorder.records.extend(Path(r) for r in records)
        self.recorder.stop = True
        if self._thread.is_alive():
            self._thread.join(timeout_s)
        return self.messages
