"""The CPUs and memory the grader is given: its cgroup's quota and limit, not the host's.

Inside a container ``os.cpu_count()`` and the load average are the host's. Gradescope's default
autograder container has 0.5 vCPU and 768 MB on a host of many cores: sized by the host, a
self-check ran four scenarios at once inside half a CPU, every recording was starved, and a
correct 30 Hz timer measured 23 Hz. Here the quota and the limit are read from the cgroup the
grader runs in and every ancestor of it (the tightest one holds): cgroup v1
``cpu.cfs_quota_us``/``cpu.cfs_period_us`` and ``memory.limit_in_bytes``, v2 ``cpu.max`` and
``memory.max``; the CPU affinity mask bounds it too. ``throttled_s`` is the time the quota held
this group back, the load signal of a quota-limited grader (the host's PSI and load average say
nothing of it).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from grader.sandbox.cgroups import _keyed, _mounts, _own_paths, _read_int

#: a v1 memory limit at or above this is "no limit" (the kernel's page-rounded LONG_MAX)
_NO_LIMIT = 1 << 60


@dataclass(frozen=True)
class Allotment:
    """What this grader may use. ``cpus``: the least of the cores, the affinity mask and the CPU
    quota; ``quota_cpus``/``memory_bytes``: the cgroup's, None when there is none."""

    cores: int
    cpus: float
    quota_cpus: float | None = None
    memory_bytes: int | None = None
    quota_dir: str | None = None       # the cgroup directory whose quota holds (its cpu.stat)

    @property
    def slots(self) -> int:
        """Whole CPUs for counting scenarios at once (at least 1)."""
        return max(1, math.ceil(self.cpus - 1e-9))


def _ancestors(mount: str, own: str) -> list[Path]:
    """Our group's directory in the tree at ``mount`` and each parent up to the mount."""
    path = Path(mount) / own.lstrip("/")
    out = [path]
    while path != Path(mount) and path.parent != path:
        path = path.parent
        out.append(path)
    return out


def _v1_quota(d: Path) -> float | None:
    quota, period = _read_int(d / "cpu.cfs_quota_us"), _read_int(d / "cpu.cfs_period_us")
    return quota / period if quota and quota > 0 and period else None


def _v2_quota(d: Path) -> float | None:
    try:
        quota, period = (d / "cpu.max").read_text().split()[:2]
    except (OSError, ValueError):
        return None
    return int(quota) / int(period) if quota != "max" and int(period) > 0 else None


def _v1_memory(d: Path) -> int | None:
    limit = _read_int(d / "memory.limit_in_bytes")
    return limit if limit is not None and limit < _NO_LIMIT else None


def _v2_memory(d: Path) -> int | None:
    try:
        text = (d / "memory.max").read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _tightest(dirs: list[Path], read: Callable[[Path], float | int | None]) -> tuple[float | None, Path | None]:
    """The least value ``read`` finds along ``dirs`` (the tightest limit), and where."""
    best: tuple[float | None, Path | None] = (None, None)
    for d in dirs:
        value = read(d)
        if value is not None and (best[0] is None or value < best[0]):
            best = (value, d)
    return best


def current() -> Allotment:
    """The allotment of this process, read afresh (a cgroup's limits can change)."""
    cores = os.cpu_count() or 1
    try:
        affinity = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        affinity = cores
    own = _own_paths()
    quota: float | None = None
    quota_dir: Path | None = None
    memory: float | None = None
    for fstype, mnt, opts in _mounts():
        if fstype == "cgroup2" and "" in own:
            dirs = _ancestors(mnt, own[""])
            q, qd = _tightest(dirs, _v2_quota)
            m, _ = _tightest(dirs, _v2_memory)
        elif fstype == "cgroup" and ("cpu" in opts or "memory" in opts):
            key = "cpu" if "cpu" in opts else "memory"
            if key not in own:
                continue
            dirs = _ancestors(mnt, own[key])
            q, qd = _tightest(dirs, _v1_quota) if "cpu" in opts else (None, None)
            m, _ = _tightest(dirs, _v1_memory) if "memory" in opts else (None, None)
        else:
            continue
        if q is not None and (quota is None or q < quota):
            quota, quota_dir = q, qd
        if m is not None and (memory is None or m < memory):
            memory = m
    cpus = float(min(cores, affinity) if quota is None else min(cores, affinity, quota))
    return Allotment(cores=cores, cpus=cpus, quota_cpus=quota,
                     memory_bytes=int(memory) if memory is not None else None,
                     quota_dir=str(quota_dir) if quota_dir is not None else None)


def throttled_s(allotment: Allotment | None = None) -> float | None:
    """Seconds the CPU quota has held the grader's group back so far (None: no quota)."""
    allotment = allotment or current()
    if allotment.quota_dir is None:
        return None
    stat = _keyed(Path(allotment.quota_dir) / "cpu.stat")
    if "throttled_usec" in stat:
        return stat["throttled_usec"] / 1e6
    if "throttled_time" in stat:
        return stat["throttled_time"] / 1e9
    return None


def describe(allotment: Allotment | None = None) -> str:
    """One line for ``grader doctor`` and the result: the CPUs and memory found, and from where."""
    a = allotment or current()
    cpu = (f"CPU quota {a.quota_cpus:g} of {a.cores} cores (cgroup)" if a.quota_cpus is not None
           else f"{a.cpus:g} CPUs" + ("" if a.cpus == a.cores else f" of {a.cores} cores (affinity)"))
    mem = f"memory limit {a.memory_bytes / 2**20:.0f} MiB (cgroup)" if a.memory_bytes else "no memory limit"
    return f"{cpu}; {mem}"


class QuotaPressure:
    """Percent of the CPU quota's periods in which the grader's group was throttled, over the
    last ``window_s`` or more (the quota's own pressure signal; PSI and the load average are
    the host's). None without a quota."""

    def __init__(self, window_s: float = 2.0) -> None:
        self.window_s = window_s
        self._last: tuple[float, int, int] | None = None
        self._value: float | None = None

    def __call__(self, allotment: Allotment, now: float) -> float | None:
        if allotment.quota_dir is None:
            return None
        stat = _keyed(Path(allotment.quota_dir) / "cpu.stat")
        periods, throttled = stat.get("nr_periods", 0), stat.get("nr_throttled", 0)
        if self._last is None:
            self._last = (now, periods, throttled)
        elif now - self._last[0] >= self.window_s:
            d_periods, d_throttled = periods - self._last[1], throttled - self._last[2]
            self._value = 100.0 * d_throttled / d_periods if d_periods > 0 else 0.0
            self._last = (now, periods, throttled)
        return self._value if self._value is not None else 0.0
