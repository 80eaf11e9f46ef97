"""Have these processes done everything they were woken for? Quiescence of process trees, from /proc.

Lockstep time (:mod:`grader.sim.clock`) advances the simulated clock only once every process the
scenario waits on has handled what the previous step sent it: then two runs of the same code see
the same messages at the same simulated times, whatever the machine's load. ROS gives no signal
for "handled" (a node may answer a pose with nothing), so we read it from the kernel: a process
tree is *quiet* when, in two scans in a row, every thread of every process in it sleeps
(state ``S``, or stopped/dead) and no thread was scheduled in between (its ``schedstat`` switch
count unchanged). The second scan closes the race of one scan: a thread read asleep, then woken
by a thread read later, shows up as a changed count of the waker (it ran to wake it) or as the
wakee running.

A message in flight wakes its reader's receive thread before the writer's ``publish`` returns
(loopback and shared-memory transports hand the data over in the writer's call), so a tree read
quiet after a publish has nothing of it left to do. Periodic DDS housekeeping (heartbeats,
announcements) wakes threads now and then: a scan then reads busy, and the caller scans again.
"""

from __future__ import annotations

import os
import time
from collections import Counter
from dataclasses import dataclass, field

#: thread states that do nothing until something wakes them (``D``, uninterruptible I/O, works on)
_IDLE_STATES = frozenset("STtZXIP")


def _read(path: str) -> str | None:
    try:
        with open(path) as f:
            return f.read()
    except OSError:                          # exited between listing and reading
        return None


def _comm(pid: int, tid: int) -> str:
    return (_read(f"/proc/{pid}/task/{tid}/comm") or "?").strip()


def descendants(roots: list[int]) -> list[int]:
    """``roots`` and every live process below them (through each thread's ``children``)."""
    out: list[int] = []
    todo = list(roots)
    seen: set[int] = set()
    while todo:
        pid = todo.pop()
        if pid in seen:
            continue
        seen.add(pid)
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        out.append(pid)
        for tid in tids:
            text = _read(f"/proc/{pid}/task/{tid}/children")
            if text:
                todo.extend(int(c) for c in text.split())
    return out


def scan(pids: list[int], exclude: set[int] | frozenset[int] = frozenset(),
         busy: list[tuple[int, int]] | None = None) -> tuple[bool, dict[int, int]]:
    """One pass: (every thread idle, each thread's count of times scheduled); threads in
    ``exclude`` (the caller's own) are left out; ``busy`` collects (pid, tid) of those awake."""
    idle = True
    counts: dict[int, int] = {}
    for pid in pids:
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            if int(tid) in exclude:
                continue
            stat = _read(f"/proc/{pid}/task/{tid}/stat")
            sched = _read(f"/proc/{pid}/task/{tid}/schedstat")
            if stat is None or sched is None:
                continue
            state = stat[stat.rindex(")") + 2]
            if state not in _IDLE_STATES:
                idle = False
                if busy is not None:
                    busy.append((pid, int(tid)))
            counts[int(tid)] = int(sched.split()[2])
    return idle, counts


@dataclass
class Quiescence:
    """Waits until the trees under ``roots`` are quiet; counts what it took."""

    roots: list[int]
    #: threads not waited for (the caller's own)
    exclude: set[int] = field(default_factory=set)
    #: rescan the tree for new processes (a launch file's children) every this many waits
    refresh_every: int = 50
    waits: int = 0
    scans: int = 0
    timeouts: int = 0
    #: the most processes waited for at once (the trees' sizes)
    processes: int = 0
    #: "<process>/<thread>" names found awake in waits that timed out, and how often
    blockers: Counter = field(default_factory=Counter)
    _pids: list[int] = field(default_factory=list)

    def refresh(self) -> None:
        """Read the trees again (a new process, a launch file's children)."""
        self._pids = descendants(self.roots)
        self.processes = max(self.processes, len(self._pids))

    def wait(self, timeout_s: float = 1.0, pause_s: float = 0.0002) -> bool:
        """Block until quiet (True) or ``timeout_s`` of wall time passed (False, counted)."""
        if self.waits % self.refresh_every == 0 or not self._pids:
            self.refresh()
        self.waits += 1
        end = time.monotonic() + timeout_s
        previous: dict[int, int] | None = None
        while True:
            busy: list[tuple[int, int]] = []
            idle, counts = scan(self._pids, self.exclude, busy)
            self.scans += 1
            if idle and counts == previous:
                return True
            previous = counts if idle else None
            if time.monotonic() >= end:
                self.timeouts += 1
                for pid, tid in busy:
                    self.blockers[f"{_comm(pid, pid)}/{_comm(pid, tid)}"] += 1
                return False
            time.sleep(pause_s)
