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
#: a wait that is not quiet gives up once its threads ran this share of its wall time on a CPU
#: (a busy loop on an idle core: at the wall limit; a thread starved of CPU: later)...
CPU_SHARE = 0.5
#: ... or after this many times its wall limit regardless
STARVED_CAP = 10.0


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
         busy: list[tuple[int, int]] | None = None,
         cpu: dict[int, int] | None = None) -> tuple[bool, dict[int, int]]:
    """One pass: (every thread idle, each thread's count of times scheduled); threads in
    ``exclude`` (the caller's own) are left out; ``busy`` collects (pid, tid) of those awake,
    ``cpu`` each thread's nanoseconds on a CPU so far."""
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
            fields = sched.split()
            counts[int(tid)] = int(fields[2])
            if cpu is not None:
                cpu[int(tid)] = int(fields[0])
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
    #: the most wall seconds a wait went on past its limit because its threads were starved
    starved_s: float = 0.0
    _pids: list[int] = field(default_factory=list)

    def refresh(self) -> None:
        """Read the trees again (a new process, a launch file's children)."""
        self._pids = descendants(self.roots)
        self.processes = max(self.processes, len(self._pids))

    def wait(self, timeout_s: float = 1.0, pause_s: float = 0.0002) -> bool:
        """Block until quiet (True) or not quiet after ``timeout_s`` of wall time in which the
        trees' threads also ran ``timeout_s * CPU_SHARE`` seconds on a CPU (False, counted).

        The CPU condition tells a busy node from a starved one: on a loaded machine a thread
        woken by the tick may wait seconds for a CPU, which a wall-clock limit alone cannot tell
        from a busy loop (at load 20, Lab 3's action server ran out of 2 s waits 6 times in
        5180 ticks, and the run went back to the wall clock). A thread waiting for a CPU runs
        none; a busy one runs whatever share it gets. ``STARVED_CAP``
        times ``timeout_s`` of wall time ends the wait in any case."""
        if self.waits % self.refresh_every == 0 or not self._pids:
            self.refresh()
        self.waits += 1
        start = time.monotonic()
        end, cap = start + timeout_s, start + timeout_s * STARVED_CAP
        previous: dict[int, int] | None = None
        first: dict[int, int] = {}
        while True:
            busy: list[tuple[int, int]] = []
            cpu: dict[int, int] = {}
            idle, counts = scan(self._pids, self.exclude, busy, cpu)
            self.scans += 1
            if idle and counts == previous:
                return True
            previous = counts if idle else None
            for tid, ns in cpu.items():
                first.setdefault(tid, ns)
            now = time.monotonic()
            ran_s = sum(ns - first[tid] for tid, ns in cpu.items()) / 1e9
            if now >= cap or (now >= end and ran_s >= timeout_s * CPU_SHARE):
                self.starved_s = max(self.starved_s, now - start - timeout_s)
                self.timeouts += 1
                for pid, tid in busy:
                    self.blockers[f"{_comm(pid, pid)}/{_comm(pid, tid)}"] += 1
                return False
            time.sleep(pause_s)
