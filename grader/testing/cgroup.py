"""A child cgroup with a CPU quota and a memory limit, for tests that grade as a small container
does (Gradescope's default: 0.5 vCPU, 768 MB): cgroup v1 (a ``cpu`` and a ``memory`` tree) or
v2, made under the cgroup this process runs in. Needs root, or a delegated cgroup."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator

from grader.sandbox.cgroups import CPU_PERIOD_US, _mounts, _own_paths

CPU_SHARES_MAX = 262144             # cgroup v1 cpu.shares
CPU_WEIGHT_MAX = 10000              # cgroup v2 cpu.weight


class LimitedGroup:
    """The group's directories; ``procs`` the files a process joins it through."""

    def __init__(self, dirs: dict[str, Path], v2: bool) -> None:
        self.dirs, self.v2 = dirs, v2

    @property
    def procs(self) -> list[str]:
        return sorted({str(d / "cgroup.procs") for d in self.dirs.values()})

    def join(self) -> None:
        """Move the calling process in (a ``preexec_fn``, or before ``exec``)."""
        for path in self.procs:
            Path(path).write_text(str(os.getpid()))

    def set_cpus(self, cpus: float | None) -> None:
        """A new CPU quota (None: none)."""
        d = self.dirs["cpu"]
        if self.v2:
            (d / "cpu.max").write_text(f"{int(cpus * CPU_PERIOD_US)} {CPU_PERIOD_US}" if cpus else "max")
        else:
            (d / "cpu.cfs_quota_us").write_text(str(int(cpus * CPU_PERIOD_US)) if cpus else "-1")


def _dirs(name: str) -> tuple[dict[str, Path], bool] | None:
    own = _own_paths()
    dirs: dict[str, Path] = {}
    for fstype, mnt, opts in _mounts():
        for key in ("cpu", "memory"):
            if fstype == "cgroup" and key in opts and key in own and key not in dirs:
                dirs[key] = Path(mnt) / own[key].lstrip("/") / name
    if set(dirs) == {"cpu", "memory"}:
        return dirs, False
    for fstype, mnt, _opts in _mounts():
        if fstype == "cgroup2" and "" in own:
            base = Path(mnt) / own[""].lstrip("/")
            controllers = (base / "cgroup.subtree_control").read_text().split() \
                if (base / "cgroup.subtree_control").exists() else []
            if {"cpu", "memory"} <= set(controllers):
                return {"cpu": base / name, "memory": base / name}, True
    return None


@contextlib.contextmanager
def limited_group(cpus: float, memory_mb: int, name: str = "") -> Iterator[LimitedGroup | None]:
    """A group of ``cpus`` CPUs and ``memory_mb`` MiB (swap off where the kernel lets us), or
    None where this machine cannot make one; removed afterwards (its processes must be gone)."""
    found = _dirs(name or f"grader-test-{os.getpid()}")
    if found is None:
        yield None
        return
    dirs, v2 = found
    try:
        for d in set(dirs.values()):
            d.mkdir(exist_ok=True)
    except OSError:
        yield None
        return
    group = LimitedGroup(dirs, v2)
    try:
        group.set_cpus(cpus)
        # a container's quota is its own: the most weight the kernel allows, so busy neighbours
        # (another test session) cannot take the group below its quota and the quota is what limits
        d = dirs["cpu"]
        (d / ("cpu.weight" if v2 else "cpu.shares")).write_text(str(CPU_WEIGHT_MAX if v2 else CPU_SHARES_MAX))
        mem = dirs["memory"]
        (mem / ("memory.max" if v2 else "memory.limit_in_bytes")).write_text(str(memory_mb * 2**20))
        yield group
    finally:
        for d in set(dirs.values()):
            with contextlib.suppress(OSError):
                d.rmdir()
