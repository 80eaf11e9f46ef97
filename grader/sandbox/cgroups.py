"""Control groups: per-scenario memory, process-count and CPU limits, and "kill everything".

An rlimit bounds one process; a cgroup bounds a scenario's student processes together, however
many they fork, and lists every one of them (a double-forked ``setsid`` daemon included), so the
grader can kill them all. Works with cgroup v1 controllers (one tree per controller, as on
Debian hosts with a hybrid layout), a v2 tree for ``cgroup.kill``, or a pure v2 machine whose
grader cgroup may delegate controllers. Groups are made under the cgroup the grader already runs
in, so whatever limits its own caller set stay in force.
"""

from __future__ import annotations

import os
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path

CONTROLLERS = ("memory", "pids", "cpu")
CPU_PERIOD_US = 100_000


@dataclass(frozen=True)
class CgroupSupport:
    """Where each controller can be used: ``bases[controller]`` is our cgroup in its tree;
    ``bases["kill"]`` a v2 tree (``cgroup.kill``) or any tree to list members from."""

    bases: dict[str, str] = field(default_factory=dict)
    v2: dict[str, bool] = field(default_factory=dict)       # controller -> lives in a v2 tree
    problem: str = ""

    memory = property(lambda self: "memory" in self.bases)
    pids = property(lambda self: "pids" in self.bases)
    cpu = property(lambda self: "cpu" in self.bases)
    kill = property(lambda self: "kill" in self.bases)

    def detail(self, what: str) -> str:
        if what not in self.bases:
            return self.problem or f"no writable cgroup with the {what} controller"
        tree = "v2" if self.v2.get(what) else "v1"
        text = {"memory": "per scenario (all its student processes together)",
                "pids": "processes and threads per scenario (stops fork bombs)",
                "cpu": "CPU quota per scenario (all its student processes together)",
                "kill": "every process of a scenario is killed at its end, detached ones too"}[what]
        return f"cgroup {tree}: {text}"


def _mounts() -> list[tuple[str, str, set[str]]]:
    """(fstype, mount point, super options) of every cgroup mount."""
    out: list[tuple[str, str, set[str]]] = []
    try:
        lines = Path("/proc/self/mountinfo").read_text().splitlines()
    except OSError:
        return out
    for line in lines:
        left, _, right = line.partition(" - ")
        fields, rfields = left.split(), right.split()
        if len(rfields) >= 3 and rfields[0] in ("cgroup", "cgroup2"):
            out.append((rfields[0], fields[4], set(rfields[2].split(","))))
    return out


def _own_paths() -> dict[str, str]:
    """Our cgroup path per hierarchy: controller names for v1, "" for v2."""
    own: dict[str, str] = {}
    try:
        lines = Path("/proc/self/cgroup").read_text().splitlines()
    except OSError:
        return own
    for line in lines:
        _hid, controllers, path = line.split(":", 2)
        for c in (controllers.split(",") if controllers else [""]):
            own[c] = path
    return own


def _writable(base: Path) -> bool:
    probe = base / f"grader-probe-{os.getpid()}"
    try:
        probe.mkdir()
        probe.rmdir()
        return True
    except OSError:
        return False


def find_cgroup_support() -> CgroupSupport:
    bases: dict[str, str] = {}
    v2: dict[str, bool] = {}
    own = _own_paths()
    v2_base: Path | None = None
    for fstype, mnt, opts in _mounts():
        if fstype == "cgroup":
            for c in CONTROLLERS:
                if c in opts and c in own and c not in bases:
                    base = Path(mnt) / own[c].lstrip("/")
                    if _writable(base):
                        bases[c] = str(base)
        elif "" in own and v2_base is None:
            base = Path(mnt) / own[""].lstrip("/")
            if _writable(base):
                v2_base = base
    if v2_base is not None:
        bases["kill"] = str(v2_base)
        v2["kill"] = True
        available = set((v2_base / "cgroup.controllers").read_text().split()) \
            if (v2_base / "cgroup.controllers").exists() else set()
        for c in CONTROLLERS:
            if c not in bases and c in available and _delegate(v2_base, c):
                bases[c], v2[c] = str(v2_base), True
    elif bases:
        bases["kill"] = next(iter(bases.values()))
    problem = "" if bases else "no writable cgroup tree (run as root, or delegate a cgroup to the grader)"
    return CgroupSupport(bases=bases, v2=v2, problem=problem)


def _delegate(base: Path, controller: str) -> bool:
    """Enable ``controller`` for our child groups (fails while our own group holds processes)."""
    try:
        (base / "cgroup.subtree_control").write_text(f"+{controller}")
        return True
    except OSError:
        return False


class CgroupSet:
    """One logical cgroup, made in every tree that ``support`` uses."""

    def __init__(self, support: CgroupSupport, dirs: dict[str, Path]) -> None:
        self.support = support
        self.dirs = dirs           # tree key ("memory", "pids", "cpu", "kill") -> directory

    @classmethod
    def create(cls, support: CgroupSupport, name: str) -> "CgroupSet":
        dirs: dict[str, Path] = {}
        for key, base in support.bases.items():
            d = Path(base) / name
            d.mkdir(exist_ok=True)
            dirs[key] = d
        return cls(support, dirs)

    def child(self, name: str) -> "CgroupSet":
        dirs: dict[str, Path] = {}
        for key, d in self.dirs.items():
            sub = d / name
            sub.mkdir(exist_ok=True)
            dirs[key] = sub
        return CgroupSet(self.support, dirs)

    def procs_files(self) -> list[str]:
        """``cgroup.procs`` of each distinct directory: writing a pid there moves the process."""
        return sorted({str(d / "cgroup.procs") for d in self.dirs.values()})

    def to_json(self) -> dict[str, str]:
        return {k: str(v) for k, v in self.dirs.items()}

    @classmethod
    def from_json(cls, data: dict[str, str], support: CgroupSupport | None = None) -> "CgroupSet":
        return cls(support or CgroupSupport(), {k: Path(v) for k, v in data.items()})

    # -- limits ---------------------------------------------------------------------------
    def _v2(self, key: str) -> bool:
        d = self.dirs.get(key)
        return d is not None and (d / "cgroup.controllers").exists()

    def set_limits(self, *, memory_bytes: int | None = None, pids: int | None = None,
                   cpus: float | None = None) -> None:
        if memory_bytes and "memory" in self.dirs:
            d = self.dirs["memory"]
            if self._v2("memory"):
                (d / "memory.max").write_text(str(memory_bytes))
                _try_write(d / "memory.swap.max", "0")
            else:
                (d / "memory.limit_in_bytes").write_text(str(memory_bytes))
        if pids and "pids" in self.dirs:
            (self.dirs["pids"] / "pids.max").write_text(str(pids))
        if cpus and "cpu" in self.dirs:
            d, quota = self.dirs["cpu"], int(cpus * CPU_PERIOD_US)
            if self._v2("cpu"):
                (d / "cpu.max").write_text(f"{quota} {CPU_PERIOD_US}")
            else:
                (d / "cpu.cfs_period_us").write_text(str(CPU_PERIOD_US))
                # v1 refuses (EINVAL) a quota above an ancestor's (a container given less than
                # this many CPUs): that ancestor's quota already holds the group back further
                _try_write(d / "cpu.cfs_quota_us", str(quota))

    def counters(self) -> dict[str, float]:
        """What the kernel counted: OOM kills, refused forks, CPU throttling, peaks."""
        out: dict[str, float] = {}
        if "memory" in self.dirs:
            d = self.dirs["memory"]
            events = _keyed(d / ("memory.events" if self._v2("memory") else "memory.oom_control"))
            out["oom_kills"] = events.get("oom_kill", 0)
            peak = _read_int(d / ("memory.peak" if self._v2("memory") else "memory.max_usage_in_bytes"))
            if peak is not None:
                out["memory_peak_bytes"] = peak
        if "pids" in self.dirs:
            d = self.dirs["pids"]
            out["forks_refused"] = _keyed(d / "pids.events").get("max", 0)
            peak = _read_int(d / "pids.peak")
            if peak is not None:
                out["pids_peak"] = peak
        if "cpu" in self.dirs:
            stat = _keyed(self.dirs["cpu"] / "cpu.stat")
            out["cpu_throttled"] = stat.get("nr_throttled", 0)
            if "throttled_usec" in stat:
                out["cpu_throttled_s"] = stat["throttled_usec"] / 1e6
            elif "throttled_time" in stat:
                out["cpu_throttled_s"] = stat["throttled_time"] / 1e9
        kill_dir = self.dirs.get("kill")
        if kill_dir is not None and (kill_dir / "cpu.stat").exists():
            usage = _keyed(kill_dir / "cpu.stat").get("usage_usec")
            if usage is not None:
                out["cpu_s"] = usage / 1e6
        return out

    # -- membership and the end ------------------------------------------------------------
    def pids(self) -> set[int]:
        found: set[int] = set()
        for d in self.dirs.values():
            # os.walk passes over a group removed while it lists (another grader's sweep of the
            # same stale group, or the group's own end); rglob raised there and ended the batch
            for sub, _groups, _files in os.walk(d):
                found.update(_read_pids(Path(sub) / "cgroup.procs"))
        return found

    def kill(self, timeout_s: float = 5.0) -> int:
        """SIGKILL every process in the group (and its children); returns how many there were."""
        victims = self.pids()
        kill_file = self.dirs.get("kill", Path("/nonexistent")) / "cgroup.kill"
        deadline = time.monotonic() + timeout_s
        while True:
            left = self.pids()
            if not left or time.monotonic() > deadline:
                return len(victims)
            victims |= left
            if kill_file.exists() and _try_write(kill_file, "1"):
                pass
            else:
                for pid in left:
                    try:
                        os.kill(pid, signal.SIGKILL)
                    except (ProcessLookupError, PermissionError):
                        pass
            time.sleep(0.01)

    def remove(self, timeout_s: float = 2.0) -> None:
        """Delete the directories (deepest first); a group still busy is retried briefly."""
        deadline = time.monotonic() + timeout_s
        for d in self.dirs.values():
            subs = sorted((p for p in d.rglob("*") if p.is_dir()), key=lambda p: -len(p.parts)) + [d]
            for sub in subs:
                while True:
                    try:
                        sub.rmdir()
                        break
                    except FileNotFoundError:
                        break
                    except OSError:
                        if time.monotonic() > deadline:
                            break
                        time.sleep(0.02)


def sweep_stale(support: CgroupSupport) -> int:
    """Remove the groups of grader processes that died without cleaning up (SIGKILL, a crash):
    ``grader-<pid>-...`` whose pid is gone. Whatever still runs in them is killed first."""
    removed = 0
    for key, base in support.bases.items():
        for d in Path(base).glob("grader-*-*"):
            pid = d.name.split("-")[1]
            if not pid.isdigit() or Path(f"/proc/{pid}").exists():
                continue
            group = CgroupSet(support, {key: d})
            group.kill(timeout_s=1.0)
            group.remove(timeout_s=0.5)
            removed += not d.exists()
    return removed


def join(procs_files: list[str]) -> None:
    """Move the calling process into a group (between fork and exec; async-signal-light)."""
    pid = str(os.getpid()).encode()
    for path in procs_files:
        fd = os.open(path, os.O_WRONLY)
        try:
            os.write(fd, pid)
        finally:
            os.close(fd)


def _try_write(path: Path, text: str) -> bool:
    try:
        path.write_text(text)
        return True
    except OSError:
        return False


def _read_int(path: Path) -> int | None:
    try:
        return int(path.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def _keyed(path: Path) -> dict[str, int]:
    out: dict[str, int] = {}
    try:
        for line in path.read_text().splitlines():
            parts = line.split()
            if len(parts) == 2 and parts[1].lstrip("-").isdigit():
                out[parts[0]] = int(parts[1])
    except OSError:
        pass
    return out


def _read_pids(path: Path) -> set[int]:
    try:
        return {int(x) for x in path.read_text().split()}
    except (OSError, ValueError):
        return set()
