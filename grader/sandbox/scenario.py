"""A scenario's sandbox: its namespaces, its cgroups, and the jail of its student processes.

Parent side (``run_scenario``): :class:`ScenarioSandbox` makes the scenario's cgroups (``grader``
for the simulator, recorder and driver; ``students`` with the limits), wraps the scenario child's
command so that it starts as PID 1 of a new PID and network namespace (``unshare`` +
``enter.py``), hands the child its student :class:`~grader.sandbox.jail.Jail` through one
environment variable, and at the end kills whatever is left in the cgroups, reads what the
kernel counted (OOM kills, refused forks, CPU throttling) and removes them.

Child side (``RosGraph``): :func:`child_config` reads that variable back.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import shutil
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from grader.contracts.scenario_record import ScenarioRecord
from grader.contracts.output_folder import SCENARIO_JSON
from grader.errors import GraderError
from grader.sandbox import allotment, cgroups
from grader.sandbox.capture import DEFAULT_CAP_BYTES
from grader.sandbox.jail import Jail, ros_roots
from grader.sandbox.probe import Capabilities, probe, protections, sandbox_uid

CONFIG_VAR = "GRADER_SANDBOX_CONFIG"
MODE_VAR = "GRADER_SANDBOX"          # auto (default) | off | require
ENTER = Path(__file__).resolve().parent / "enter.py"
#: CPU throttling below this total is start-up noise, not worth a line in the record
CPU_REPORT_S = 1.0
_SEQ = itertools.count(1)


@dataclass(frozen=True)
class SandboxPolicy:
    """Limits of one scenario's student processes together (environment overrides in brackets)."""

    memory_mb: int = 2048           # GRADER_SANDBOX_MEMORY_MB (default_memory_mb under a memory limit); a rubric scenario's limits.memory_mb wins
    pids: int = 512                 # GRADER_SANDBOX_PIDS: processes + threads (an rclpy node has ~15)
    cpus: float = 1.0               # GRADER_SANDBOX_CPUS: CPU quota (0: none)
    output_cap_bytes: int = DEFAULT_CAP_BYTES   # GRADER_SANDBOX_OUTPUT_MB, per stream and process
    scratch_mb: int = 256           # GRADER_SANDBOX_SCRATCH_MB: the /sandbox tmpfs of each process

    @classmethod
    def from_env(cls, memory_mb: int | None = None) -> "SandboxPolicy":
        env = os.environ
        try:
            return cls(memory_mb=memory_mb or int(env.get("GRADER_SANDBOX_MEMORY_MB") or default_memory_mb()),
                       pids=int(env.get("GRADER_SANDBOX_PIDS") or cls.pids),
                       cpus=float(env.get("GRADER_SANDBOX_CPUS") or cls.cpus),
                       output_cap_bytes=int(float(env.get("GRADER_SANDBOX_OUTPUT_MB") or 10) * 2**20),
                       scratch_mb=int(env.get("GRADER_SANDBOX_SCRATCH_MB") or cls.scratch_mb))
        except ValueError as exc:
            raise GraderError(f"bad GRADER_SANDBOX_* setting: {exc}") from None


def default_memory_mb(given: allotment.Allotment | None = None) -> int:
    """The student processes' memory of one scenario: ``SandboxPolicy.memory_mb``, or half the
    grader's own memory limit where that is less (a 768 MB Gradescope container: 384 MiB), so
    a student's leak is stopped by its scenario's limit before the container's kills the grader."""
    given = given or allotment.current()
    if given.memory_bytes is None:
        return SandboxPolicy.memory_mb
    return max(128, min(SandboxPolicy.memory_mb, given.memory_bytes // 2 // 2**20))


def sandbox_mode() -> str:
    mode = (os.environ.get(MODE_VAR) or "auto").strip().lower()
    aliases = {"0": "off", "no": "off", "false": "off", "1": "auto", "on": "auto", "yes": "auto"}
    mode = aliases.get(mode, mode)
    if mode not in ("auto", "off", "require"):
        raise GraderError(f"{MODE_VAR}={mode!r}: use auto, off or require")
    return mode


def summary(caps: Capabilities | None = None) -> dict[str, Any]:
    """Which protections are active, for result.json; ``warning`` when any is missing."""
    mode = sandbox_mode()
    rows = protections(caps, enabled=mode != "off")
    missing = [p.name for p in rows if not p.active]
    out: dict[str, Any] = {"mode": mode, "active": [p.name for p in rows if p.active], "missing": missing}
    if missing:
        out["warning"] = ("student code ran with reduced isolation: " + "; ".join(
            f"{p.name} off ({p.detail})" for p in rows if not p.active))
    return out


def require_complete(caps: Capabilities | None = None) -> None:
    if sandbox_mode() == "require":
        missing = [p for p in protections(caps) if not p.active]
        if missing:
            raise GraderError("GRADER_SANDBOX=require, but these protections are unavailable: " + "; ".join(
                f"{p.name} ({p.detail})" for p in missing))


def _extra_ro(prefixes: Sequence[str], env: Mapping[str, str]) -> list[str]:
    """The build's ``install`` and ``src`` trees (and the simulator overlay that the system's
    ``ros2 launch`` uses), and the ROS installs on ``env`` (a sourced system ROS wherever it is)."""
    ro: list[str] = []
    for prefix in prefixes:
        install = Path(prefix).parent
        for tree in (install, install.parent / "src", install.parent / "grader-sim-overlay"):
            if tree.is_dir() and str(tree) not in ro:
                ro.append(str(tree))
    return ro + [r for r in ros_roots(env) if r not in ro]


def student_jail(caps: Capabilities, policy: SandboxPolicy, *, ro: Sequence[str] = (),
                 rw: Sequence[str] = (), own_network: bool = False,
                 cgroup: cgroups.CgroupSet | None = None) -> Jail:
    """The jail of student code on this machine (bubblewrap when it works, else the fallback)."""
    return Jail(bwrap=caps.bwrap, ro=tuple(ro), rw=tuple(rw), scratch_mb=policy.scratch_mb,
                scratch_cap=caps.bwrap_size, own_network=own_network, uid=sandbox_uid() if caps.uid_drop else None,
                signal_reset=caps.signal_reset,
                cgroup_procs=tuple(cgroup.procs_files()) if cgroup is not None else ())


_SWEPT = False


def _sweep_once(support: cgroups.CgroupSupport) -> None:
    global _SWEPT
    if not _SWEPT:
        _SWEPT = True
        cgroups.sweep_stale(support)


class ScenarioSandbox:
    """Namespaces, cgroups and the student jail of one scenario run (a context manager)."""

    def __init__(self, *, prefixes: Sequence[str] = (), env: Mapping[str, str] | None = None,
                 memory_mb: int | None = None, name: str = "scenario") -> None:
        self.mode = sandbox_mode()
        self.caps = probe()
        require_complete(self.caps)
        self.policy = SandboxPolicy.from_env(memory_mb)
        self.enabled = self.mode != "off"
        self.netns = self.enabled and self.caps.netns
        self.group: cgroups.CgroupSet | None = None
        self.runner: cgroups.CgroupSet | None = None
        self.students: cgroups.CgroupSet | None = None
        self.left_running = 0
        self.counters: dict[str, float] = {}
        self._prefixes = tuple(prefixes)
        self._env = dict(env or os.environ)
        self._name = f"grader-{os.getpid()}-{next(_SEQ)}-" + re.sub(r"[^A-Za-z0-9_.-]", "_", name)[:40]
        self.jail: Jail | None = None

    def __enter__(self) -> "ScenarioSandbox":
        if not self.enabled:
            return self
        if self.caps.cgroups.bases:
            _sweep_once(self.caps.cgroups)
            self.group = cgroups.CgroupSet.create(self.caps.cgroups, self._name)
            self.runner = self.group.child("grader")
            self.students = self.group.child("students")
            self.students.set_limits(memory_bytes=self.policy.memory_mb * 2**20, pids=self.policy.pids,
                                     cpus=self.policy.cpus or None)
        self.jail = student_jail(self.caps, self.policy, ro=_extra_ro(self._prefixes, self._env),
                                 cgroup=self.students)
        return self

    def argv(self, inner: Sequence[str]) -> list[str]:
        """The scenario child's command: as PID 1 of its own namespaces, inside its cgroup."""
        if not self.enabled or (not self.netns and self.runner is None):
            return list(inner)
        enter = [sys.executable, "-S", str(ENTER)]
        for f in (self.runner.procs_files() if self.runner is not None else []):
            enter += ["--procs", f]
        if self.netns:
            user = [] if self.caps.root else ["--user", "--map-root-user"]
            return [shutil.which("unshare") or "unshare", *user, "--net", "--pid", "--fork", "--kill-child",
                    "--mount-proc", *enter, "--loopback", "--", *inner]
        return [*enter, "--", *inner]

    def env(self, base: Mapping[str, str]) -> dict[str, str]:
        out = dict(base)
        if not self.enabled or self.jail is None:
            out.pop(CONFIG_VAR, None)
            return out
        config = {"jail": self.jail.to_json(), "netns": self.netns, "policy": asdict(self.policy),
                  "students": self.students.to_json() if self.students is not None else None}
        out[CONFIG_VAR] = json.dumps(config)
        if self.netns:
            # the namespace holds only this scenario; multicast discovery on its loopback works and
            # lets the sandboxed students use the UDP-only profile (LOCALHOST mode forces shm)
            out["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
        return out

    def __exit__(self, *exc: object) -> None:
        if self.group is None:
            return
        try:
            self.left_running = self.group.kill()
            self.counters = self.students.counters() if self.students is not None else {}
        finally:
            self.group.remove()

    def limits_hit(self) -> list[dict[str, Any]]:
        """Each limit the scenario's student processes reached, by name, from the kernel's counts."""
        c, p = self.counters, self.policy
        hits: list[dict[str, Any]] = []
        if c.get("oom_kills"):
            hits.append({"limit": "memory", "count": int(c["oom_kills"]),
                         "detail": f"memory limit of {p.memory_mb} MiB for the scenario's student processes "
                                   f"reached: the kernel killed {int(c['oom_kills'])} process(es)"})
        if c.get("forks_refused"):
            hits.append({"limit": "processes", "count": int(c["forks_refused"]),
                         "detail": f"process limit of {p.pids} processes/threads reached: "
                                   f"{int(c['forks_refused'])} fork(s) or thread(s) refused"})
        if c.get("cpu_throttled_s", 0.0) >= CPU_REPORT_S:
            hits.append({"limit": "cpu", "seconds": round(c["cpu_throttled_s"], 2),
                         "detail": f"CPU limit of {p.cpus:g} CPU(s): the student processes were held back "
                                   f"for {c['cpu_throttled_s']:.1f} s"})
        return hits

    def report(self, record: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The ``sandbox`` entry of scenario.json: protections, limits hit, counters."""
        out = summary(self.caps)
        hits = self.limits_hit()
        for cut in (record or {}).get("output_cut", []) or []:
            hits.append({"limit": "output", **cut})
        out.update({"limits_hit": hits, "counters": {k: round(v, 3) for k, v in self.counters.items()},
                    "left_running": self.left_running, "policy": asdict(self.policy)})
        return out


@dataclass(frozen=True)
class ChildConfig:
    """What the scenario child needs to sandbox its student processes."""

    jail: Jail
    netns: bool
    policy: SandboxPolicy
    students: cgroups.CgroupSet | None


def child_config(env: Mapping[str, str] | None = None) -> ChildConfig | None:
    raw = (env if env is not None else os.environ).get(CONFIG_VAR)
    if not raw:
        return None
    data = json.loads(raw)
    students = cgroups.CgroupSet.from_json(data["students"]) if data.get("students") else None
    return ChildConfig(jail=Jail.from_json(data["jail"]), netns=bool(data.get("netns")),
                       policy=SandboxPolicy(**data["policy"]), students=students)


def recorded_summary(scenario_dirs: Sequence[Path]) -> dict[str, Any] | None:
    """The protections student code actually ran under, from the scenarios' records (so
    ``grader regrade`` on another machine reports the grading run, not itself). None when no
    scenario recorded it (a batch graded before the sandbox existed)."""
    seen = []
    for d in scenario_dirs:
        try:
            record = ScenarioRecord.read(Path(d) / SCENARIO_JSON)
        except (OSError, ValueError):
            continue
        if record.sandbox is not None:
            seen.append(record.sandbox)
    if not seen:
        return None
    missing = sorted({m for s in seen for m in s.get("missing", [])})
    out: dict[str, Any] = {"mode": seen[0].get("mode", "auto"),
                           "active": sorted(set.intersection(*(set(s.get("active", [])) for s in seen))),
                           "missing": missing,
                           "limits_hit": [h.get("detail", "") for s in seen for h in s.get("limits_hit", [])],
                           "left_running": sum(int(s.get("left_running", 0)) for s in seen)}
    warnings = sorted({s["warning"] for s in seen if s.get("warning")})
    if warnings:
        out["warning"] = warnings[0]
    return out
