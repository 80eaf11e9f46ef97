"""Have these processes done everything they were woken for? Quiescence of process trees, from /proc.

Lockstep time (:mod:`grader.sim.clock`) advances the simulated clock only once every process the
scenario waits on has handled what the previous step sent it: then two runs of the same code see
the same messages at the same simulated times, whatever the machine's load. ROS gives no signal
for "handled" (a node may answer a pose with nothing), so we read it from the kernel: a process
tree is *quiet* when every thread of every process in it sleeps (state ``S``, or stopped/dead)
and no thread was scheduled while that was read: each thread's ``schedstat`` switch count is the
same before and after its state was read. The counts read on both sides close the race of one
pass: a thread read asleep, then woken by a thread read later, shows up as a changed count of
the waker (it ran to wake it) or of the wakee (it ran); a thread that waits for a CPU the whole
time reads ``R``. (Earlier, two full passes in a row had to read idle with equal counts: at
least 5 ms a check on Lab 3's action scenario, where the counts-states-counts check through
:class:`TaskFiles` takes ~0.4 ms.)

A scan stops reading states at the first thread awake (the one found the scan before is read
first), and the pause between scans doubles from 0.2 ms to 1 ms while they find work: a scan
that finds a thread awake is not quiet whatever the rest read, and a node that takes longer is
polled less. Microbenchmarked (4 processes of 16 threads, one thread working 0.5/2/8 ms after
each poke, load 9-13): 1.27/1.49/2.88 ms of CPU per wait instead of 1.33/2.37/3.32, the wait
ending 4.0/5.7/6.6 ms after the work instead of 6.0/8.4/9.3 (medians).

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


class TaskFiles:
    """Each thread's ``stat`` and ``schedstat``, opened once and re-read with ``pread``.

    A quiet check reads both files of every thread of the scenario's processes, several times a
    tick. Opened and closed each time, one pass over Lab 3's action scenario (4 processes, 64
    threads) took 2.53 ms, and lockstep ticks spent most of their 20 ms there (2117 ticks, 14,005
    passes); re-read through open descriptors the same pass takes 0.31 ms, the ``schedstat``
    files alone 0.07 ms. (``/proc`` regenerates these files at each read from offset 0; the
    descriptor of a thread that exited reads ``ESRCH``, and is dropped.) At most ``limit``
    threads are kept open (a node that floods threads must not exhaust the scenario process's
    descriptors); the rest are opened at each read as before."""

    def __init__(self, limit: int = 160) -> None:
        self.limit = limit
        self._fds: dict[tuple[int, int], tuple[int, int]] = {}

    def read(self, pid: int, tid: int, which: int) -> bytes | None:
        """``which`` 0: ``stat``, 1: ``schedstat``; None once the thread is gone."""
        key = (pid, tid)
        fds = self._fds.get(key)
        if fds is None:
            if len(self._fds) >= self.limit:
                name = ("stat", "schedstat")[which]
                text = _read(f"/proc/{pid}/task/{tid}/{name}")
                return None if text is None else text.encode()
            try:
                stat = os.open(f"/proc/{pid}/task/{tid}/stat", os.O_RDONLY | os.O_CLOEXEC)
            except OSError:
                return None
            try:
                sched = os.open(f"/proc/{pid}/task/{tid}/schedstat", os.O_RDONLY | os.O_CLOEXEC)
            except OSError:
                os.close(stat)
                return None
            fds = self._fds[key] = (stat, sched)
        try:
            return os.pread(fds[which], 4096, 0) or None
        except OSError:
            self._drop(key)
            return None

    def keep_only(self, live: set[tuple[int, int]]) -> None:
        """Close the files of threads no longer listed."""
        for key in [k for k in self._fds if k not in live]:
            self._drop(key)

    def _drop(self, key: tuple[int, int]) -> None:
        for fd in self._fds.pop(key, ()):
            try:
                os.close(fd)
            except OSError:
                pass

    def close(self) -> None:
        self.keep_only(set())


def threads(pids: list[int], exclude: set[int] | frozenset[int] = frozenset()) -> list[tuple[int, int]]:
    """(pid, tid) of every thread of ``pids`` but those in ``exclude`` (the caller's own)."""
    out: list[tuple[int, int]] = []
    for pid in pids:
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        out.extend((pid, int(tid)) for tid in tids if int(tid) not in exclude)
    return out


def counts(tasks: list[tuple[int, int]], files: TaskFiles,
           cpu: dict[int, int] | None = None) -> dict[int, int]:
    """Each thread's count of times scheduled (``schedstat``), and into ``cpu`` its nanoseconds
    on a CPU so far."""
    out: dict[int, int] = {}
    for pid, tid in tasks:
        sched = files.read(pid, tid, 1)
        if sched is None:
            continue
        fields = sched.split()
        out[tid] = int(fields[2])
        if cpu is not None:
            cpu[tid] = int(fields[0])
    return out


def _is_awake(files: TaskFiles, pid: int, tid: int) -> bool:
    stat = files.read(pid, tid, 0)
    return stat is not None and chr(stat[stat.rindex(b")") + 2]) not in _IDLE_STATES


def awake(tasks: list[tuple[int, int]], files: TaskFiles) -> list[tuple[int, int]]:
    """The threads not asleep (running, waiting for a CPU, in uninterruptible I/O)."""
    return [(pid, tid) for pid, tid in tasks if _is_awake(files, pid, tid)]


def first_awake(tasks: list[tuple[int, int]], files: TaskFiles,
                hint: tuple[int, int] | None = None) -> tuple[int, int] | None:
    """A thread not asleep, or None: ``hint`` (the one found last time) first, then in order,
    stopping at the first. A scan that finds one is not quiet whatever the rest read, and the
    ``stat`` reads are most of a scan's cost (64 threads: 260 us of ``stat``, 100 us of
    ``schedstat``); the thread found awake is most often the one found the time before."""
    if hint is not None and hint in tasks and _is_awake(files, *hint):
        return hint
    for pid, tid in tasks:
        if (pid, tid) != hint and _is_awake(files, pid, tid):
            return (pid, tid)
    return None


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
    _files: TaskFiles = field(default_factory=TaskFiles)
    #: the thread the last scan found awake, read first in the next (:func:`first_awake`)
    _hint: tuple[int, int] | None = None

    def close(self) -> None:
        """Close the threads' files (they are reopened on the next wait)."""
        self._files.close()

    def refresh(self) -> None:
        """Read the trees again (a new process, a launch file's children)."""
        self._pids = descendants(self.roots)
        self.processes = max(self.processes, len(self._pids))

    def wait(self, timeout_s: float = 1.0, pause_s: float = 0.0002, max_pause_s: float = 0.001) -> bool:
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
        tasks = threads(self._pids, self.exclude)
        self._files.keep_only(set(tasks))
        first: dict[int, int] = {}
        previous = counts(tasks, self._files, first)
        pause = pause_s
        while True:
            busy = first_awake(tasks, self._files, self._hint)
            self._hint = busy or self._hint
            cpu: dict[int, int] = {}
            now_counts = counts(tasks, self._files, cpu)
            self.scans += 1
            if busy is None and now_counts == previous:
                return True
            previous = now_counts
            now = time.monotonic()
            ran_s = sum(ns - first.get(tid, ns) for tid, ns in cpu.items()) / 1e9
            if now >= cap or (now >= end and ran_s >= timeout_s * CPU_SHARE):
                self.starved_s = max(self.starved_s, now - start - timeout_s)
                self.timeouts += 1
                for pid, tid in awake(tasks, self._files):
                    self.blockers[f"{_comm(pid, pid)}/{_comm(pid, tid)}"] += 1
                return False
            time.sleep(pause)
            pause = min(2 * pause, max_pause_s)
            tasks = threads(self._pids, self.exclude)
