"""How much runs at once: a budget of concurrent scenarios (and builds) shared by a batch.

Scenarios are independent (each has its own simulator, recorder and graph), and most of their
time is real time (the turtle driving, replay pacing), not CPU. So the unit of parallelism is the
scenario, not the submission: ``--jobs N`` lets N scenarios (or builds) run at once across the
whole batch, and one submission's scenarios run side by side when slots are free. A self-check
then takes about as long as its longest scenario instead of the sum.

``--jobs`` is an upper bound, not a promise: a scenario runs in real time, and one that does not
get the CPU when its timers fire measures something else (a 30 Hz controller published at 21 Hz,
the simulator's poses arrived in bursts that looked like a second publisher). Measured with
``benchmarks/bench_flake.py`` on 18 mutated Lab 3 submissions: at ``--jobs 8`` on 2 cores (load
rising to 45) 42 of 198 item results differed from ``--jobs 2`` and ``4``. So beyond the number of
cores a slot is given only while the CPUs have room: the kernel's CPU pressure (``/proc/pressure/cpu``,
the share of the last 10 s in which some task waited for a CPU) below ``PRESSURE_MAX``, and at most
one such extra slot every ``RAMP_S`` (the pressure average lags what was just started). On a
quiet machine ``--jobs 8`` still runs eight scenarios; on a saturated one it runs one per core,
like ``--jobs 2``, and grades like it.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from typing import Callable, Iterator

from grader.sandbox import allotment
from grader.sandbox.allotment import Allotment

#: above the cores, a new slot needs the CPU pressure (some avg10, %) below this
PRESSURE_MAX = 40.0
#: seconds between two slots given above the cores
RAMP_S = 10.0
#: memory one scenario takes at its peak (simulator, recorder, scenario process, a student's
#: nodes), to bound the default jobs by a memory limit: the Lab 3 self-check peaked near 600 MB
#: with its scenarios side by side
SCENARIO_MEMORY_MB = 300
PRESSURE_FILE = "/proc/pressure/cpu"


def default_jobs(given: Allotment | None = None, *, time_scale: float = 1.0) -> int:
    """Concurrent scenarios when the user does not say: twice the CPUs the grader is given (its
    cgroup's quota, not the host's cores: ``grader.sandbox.allotment``), at least 1, and no more
    than its memory limit holds at ``SCENARIO_MEMORY_MB`` each.

    ``time_scale``: given by a self-check (one submission), whose scenarios on simulated time
    (above 1; lockstep runs as fast as its ticks) wait on their processes, not on the clock, and
    take about a CPU each: one per CPU. Measured on 2 cores, the Lab 3 reference's self-check at
    4x: with four scenarios side by side one of the five was starved and recorded again at 1x in
    5 of 8 runs (wall 36-83 s, mean 58 s; CPU 53-80 s), two at a time in 1 of 7 (wall 39-43 s but
    that one 73 s; CPU 50-57 s). A batch keeps twice the CPUs: its builds and scenarios share the
    slots, and a class of 31 Lab 3 submissions graded about 1.5 per minute at 4 jobs, 1.1 at 2
    (benchmarks/README.md, issue 35)."""
    given = given or allotment.current()
    jobs = max(1, round((1 if time_scale > 1 else 2) * given.cpus))
    if given.memory_bytes:
        jobs = min(jobs, max(1, given.memory_bytes // (SCENARIO_MEMORY_MB * 2**20)))
    return jobs


_QUOTA_PRESSURE = allotment.QuotaPressure()


def cpu_pressure() -> float:
    """Percent of the last 10 s in which some task waited for a CPU (Linux PSI); under a CPU
    quota, the share of the quota's periods in which the grader's group was throttled (the
    host's PSI says nothing of the quota); without either, the 1-minute load average over the
    cores, as a percentage (100 = every core busy)."""
    quota = _QUOTA_PRESSURE(allotment.current(), time.monotonic())
    if quota is not None:
        return quota
    try:
        with open(PRESSURE_FILE) as f:
            for line in f:
                if line.startswith("some"):
                    return float(line.split("avg10=")[1].split()[0])
    except (OSError, IndexError, ValueError):
        pass
    return 100.0 * os.getloadavg()[0] / (os.cpu_count() or 1)


class Slots:
    """A counting semaphore with a name for what it bounds, that gives slots beyond the cores
    only while the CPUs have room (see the module docstring). ``pressure``/``cores``/``clock``
    are for tests."""

    def __init__(self, n: int, *, pressure: Callable[[], float] = cpu_pressure, cores: int | None = None,
                 clock: Callable[[], float] = time.monotonic, poll_s: float = 0.5) -> None:
        if n < 1:
            raise ValueError("a batch needs at least one slot")
        self.n = n
        self._sem = threading.BoundedSemaphore(n)
        self._lock = threading.Lock()
        self._pressure, self._clock, self._poll = pressure, clock, poll_s
        self.cores = cores or allotment.current().slots
        self.active = 0
        self.peak = 0                        # most slots in use at once
        self.deferred_s = 0.0                # time slots waited for the CPUs to have room
        self._last_extra = float("-inf")

    def _admit(self) -> bool:
        with self._lock:
            now = self._clock()
            extra = self.active >= self.cores
            if extra and (now - self._last_extra < RAMP_S or self._pressure() >= PRESSURE_MAX):
                return False
            if extra:
                self._last_extra = now
            self.active += 1
            self.peak = max(self.peak, self.active)
            return True

    @contextlib.contextmanager
    def taken(self) -> Iterator[None]:
        with self._sem:
            t0 = self._clock()
            while not self._admit():
                time.sleep(self._poll)
            with self._lock:
                self.deferred_s += self._clock() - t0
            try:
                yield
            finally:
                with self._lock:
                    self.active -= 1
