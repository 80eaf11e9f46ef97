"""How long a scenario's processes waited for a CPU: the measure of a starved run.

A scenario runs in real time; when its simulator or a student's node is runnable but gets no CPU
(a saturated machine), its timers fire late and its messages bunch up, and what is recorded is
no longer what the code does. The kernel counts that wait per thread (``/proc/<pid>/task/<tid>/
schedstat``: time on a CPU, time waiting on a run queue, in ns). ``wait_share`` is the wait over
the process's lifetime: ~0.1 for the simulator on this 2-core machine at load 20, far more when
starved. Recorded in ``scenario.json`` (``cpu_wait``) for every process still running at the
end (a process tree: a jailed process's own children count with it), so a grade that differs
between two runs can be read against how starved each run was.
"""

from __future__ import annotations

import os
from typing import Callable, Mapping

from grader.scenario.quiescence import descendants

_TICKS = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def thread_schedstat(pid: int) -> dict[int, tuple[int, int]]:
    """``tid -> (ns on a CPU, ns waiting on a run queue)`` for each live thread of the process."""
    out: dict[int, tuple[int, int]] = {}
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/schedstat") as f:
                a, b = f.read().split()[:2]
            out[int(tid)] = (int(a), int(b))
        except (OSError, ValueError):
            continue
    return out


def schedstat(pid: int) -> tuple[int, int]:
    """Nanoseconds on a CPU and waiting on a run queue, summed over the process's live threads."""
    threads = thread_schedstat(pid).values()
    return sum(c for c, _ in threads), sum(w for _, w in threads)


def _age_s(pid: int) -> float | None:
    """Seconds since the process started (from its start time in clock ticks after boot)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            start = int(f.read().rsplit(")", 1)[1].split()[19]) / _TICKS
        with open("/proc/uptime") as f:
            up = float(f.read().split()[0])
        return max(0.0, up - start)
    except (OSError, IndexError, ValueError):
        return None


def cpu_wait(pids: Mapping[str, int | None]) -> dict[str, dict[str, float]]:
    """``{name: {cpu_s, wait_s, alive_s, wait_share}}`` for each live process tree of ``pids``."""
    if not os.path.exists("/proc/self/task"):
        return {}
    out: dict[str, dict[str, float]] = {}
    for name, pid in pids.items():
        if pid is None or not os.path.exists(f"/proc/{pid}"):
            continue
        age = _age_s(pid)
        cpu = wait = 0
        for p in descendants([pid]):
            c, w = schedstat(p)
            cpu, wait = cpu + c, wait + w
        entry = {"cpu_s": round(cpu / 1e9, 3), "wait_s": round(wait / 1e9, 3)}
        if age:
            entry.update(alive_s=round(age, 1), wait_share=round(wait / 1e9 / age, 3))
        out[name] = entry
    return out


class TreeCpu:
    """CPU time the process trees of ``pids()`` used since :meth:`mark`, a process that ended
    keeping what it had used when last seen (its ``schedstat`` is gone with it).

    For a node that only answers its messages the load moves this far less than the wall time
    (Lab 3's action server 0.36-0.45 CPU s per simulated second while its ticks took 2.5-7.8
    times their time); a thread that spins takes what CPU is free. With the ticks' wall time,
    lockstep's measure of a node that keeps waking the others (:mod:`grader.scenario.lockstep`).
    """

    def __init__(self, pids: Callable[[], list[int]]) -> None:
        self._pids = pids
        self._seen: dict[int, int] = {}
        self._base = 0

    def _total_ns(self) -> int:
        for pid in descendants(self._pids()):
            cpu = schedstat(pid)[0]
            if cpu > self._seen.get(pid, 0):
                self._seen[pid] = cpu
        return sum(self._seen.values())

    def mark(self) -> None:
        self._base = self._total_ns()

    def used_s(self) -> float:
        return (self._total_ns() - self._base) / 1e9
