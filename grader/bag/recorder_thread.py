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
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Sequence

from grader.bag.recorder import Recorder, build_parser, recorder_argv
from grader.errors import GraderError


class RecorderThread:
    """``start()`` returns once the first discovery round is done (like ``READY``);
    ``stop()`` drains, finalizes the bag and returns the number of messages written."""

    def __init__(self, out_dir: Path | str, topics: Sequence[str] | None = None, *, domain_id: int,
                 extra: Sequence[str] = (), local: Sequence[str] = ()) -> None:
        """``local``: ``std_msgs/msg/String`` topics this process writes itself (:meth:`post`);
        a node publishing on them over DDS is not recorded."""
        argv = recorder_argv(out_dir, topics, extra=extra)[3:]     # the CLI's options and defaults
        self.recorder = Recorder(build_parser().parse_args(argv), domain_id=domain_id)
        for topic in local:
            self.recorder.add_local(topic, "std_msgs/msg/String")
        self.ready = threading.Event()
        self.error: BaseException | None = None
        self.messages: int | None = None
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)

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
