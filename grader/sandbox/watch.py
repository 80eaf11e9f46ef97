"""Limits as they are hit, while the scenario runs: an event the moment a log is cut or the
kernel kills or refuses something in the scenario's student cgroup (the scenario record gets
the final counts from :class:`~grader.sandbox.scenario.ScenarioSandbox` afterwards)."""

from __future__ import annotations

import threading
from typing import Any

from grader.sandbox.scenario import CPU_REPORT_S, ChildConfig
class LimitWatch:
    """Reports each limit as it is hit: output caps of the graph's processes, and the kernel's
    counts for the scenario's student cgroup (OOM kills, refused forks, CPU throttling), polled
    twice a second.

    ``on_limit(limit=..., detail=..., **fields)`` is set by the scenario child (it emits a
    ``limit_hit`` event); hits before it is set are kept and delivered when it is.
    """

    POLL_S = 0.5

    def __init__(self, sandbox: ChildConfig | None) -> None:
        self._sandbox = sandbox
        self._pending: list[dict] = []
        self._callback = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._seen: dict[str, float] = {}
        self._thread: threading.Thread | None = None
        if sandbox is not None and sandbox.students is not None:
            self._thread = threading.Thread(target=self._poll, name="limit-watch", daemon=True)
            self._thread.start()

    @property
    def on_limit(self):
        return self._callback

    @on_limit.setter
    def on_limit(self, callback) -> None:
        with self._lock:
            self._callback = callback
            pending, self._pending = self._pending, []
        for fields in pending:
            self._emit(fields)

    def _emit(self, fields: dict) -> None:
        with self._lock:
            callback = self._callback
            if callback is None:
                self._pending.append(fields)
                return
        try:
            callback(**fields)
        except Exception:  # noqa: BLE001 - a report must never break the scenario
            pass

    def watch_output(self, proc: Any) -> None:
        previous = proc.on_output_cut

        def on_cut(stream: str, cap: int) -> None:
            previous(stream, cap)
            self._emit({"limit": "output", "process": proc.name, "stream": stream,
                        "detail": f"{proc.name}: {stream} cut at {cap / 2**20:g} MiB (output limit)"})

        proc.on_output_cut = on_cut      # type: ignore[method-assign]

    def _poll(self) -> None:
        assert self._sandbox is not None and self._sandbox.students is not None
        group, policy = self._sandbox.students, self._sandbox.policy
        while not self._stop.wait(self.POLL_S):
            counts = group.counters()
            for key, limit, text in (
                    ("oom_kills", "memory", f"memory limit of {policy.memory_mb} MiB for the scenario's "
                                            "student processes reached: the kernel killed a process"),
                    ("forks_refused", "processes", f"process limit of {policy.pids} processes/threads "
                                                   "reached: forks refused")):
                if counts.get(key, 0) > self._seen.get(key, 0):
                    self._seen[key] = counts[key]
                    self._emit({"limit": limit, "count": int(counts[key]), "detail": text})
            throttled = counts.get("cpu_throttled_s", 0.0)
            if throttled >= CPU_REPORT_S and "cpu" not in self._seen:
                self._seen["cpu"] = throttled           # once: the record has the final total
                self._emit({"limit": "cpu", "seconds": round(throttled, 2),
                            "detail": f"CPU limit of {policy.cpus:g} CPU(s): the student processes are "
                                      f"being held back ({throttled:.1f} s so far)"})

    def stop(self) -> None:
        self._stop.set()
