"""What this machine lets the sandbox use, found once per process by trying each tool for real.

Every protection rests on a kernel feature or a tool that a machine may lack or forbid
(containers without user namespaces, read-only cgroup trees, no bubblewrap). ``probe()`` tries
each one with a trivial command (about 30 ms in all) and keeps the answer; ``protections()``
turns it into the list that ``grader doctor`` prints and every result records.
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

from grader.sandbox.cgroups import CgroupSupport, find_cgroup_support

#: the user student code runs as when the grader runs as root (Debian's ``nobody``)
DEFAULT_UID = 65534
PROBE_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class Capabilities:
    """What worked on this machine (``None``/``False``: not available, see ``why``)."""

    root: bool
    bwrap: str | None = None                 # path of a working bubblewrap
    bwrap_version: str = ""
    bwrap_size: bool = False                 # bubblewrap >= 0.7 caps a tmpfs (--size); Ubuntu 22.04 has 0.6
    uid_drop: bool = False                   # root: setpriv inside bwrap switches to an unprivileged uid
    signal_reset: bool = False               # `env --default-signal` (bwrap ignores Ctrl-C, the payload not)
    netns: bool = False                      # `unshare --net --pid --fork` for a scenario
    cgroups: CgroupSupport = field(default_factory=CgroupSupport)
    why: dict[str, str] = field(default_factory=dict)   # protection -> why it is missing

    def as_dict(self) -> dict:
        return asdict(self)


def _try(argv: list[str]) -> tuple[bool, str]:
    try:
        proc = subprocess.run(argv, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                              timeout=PROBE_TIMEOUT_S, errors="replace")
    except (OSError, subprocess.TimeoutExpired) as exc:
        return False, str(exc)
    last = (proc.stderr.strip().splitlines() or [f"exit code {proc.returncode}"])[-1]
    return proc.returncode == 0, last


def sandbox_uid() -> int:
    return int(os.environ.get("GRADER_SANDBOX_UID") or DEFAULT_UID)


def _bwrap_base(bwrap: str, size: bool) -> list[str]:
    """Every option the jail uses, on a trivial view (``--size`` only where it exists)."""
    return [bwrap, "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc", "--unshare-pid",
            "--unshare-ipc", "--unshare-net", "--unshare-uts", "--hostname", "sandbox", "--unshare-cgroup-try",
            "--die-with-parent", "--perms", "01777", *(["--size", "1048576"] if size else []), "--tmpfs", "/tmp",
            "--perms", "0755", "--dir", "/tmp/probe", "--symlink", "/tmp/probe", "/tmp/link", "--chdir", "/tmp"]


def _probe_bwrap(root: bool, why: dict[str, str]) -> tuple[str | None, str, bool, bool, bool]:
    bwrap = shutil.which(os.environ.get("GRADER_BWRAP") or "bwrap")
    if bwrap is None:
        why["filesystem"] = "bubblewrap is not installed (Debian/Ubuntu package `bubblewrap`)"
        why["unprivileged user"] = why["graceful stop"] = "needs bubblewrap"
        return None, "", False, False, False
    version = subprocess.run([bwrap, "--version"], capture_output=True, text=True).stdout.strip()
    size = True
    base = _bwrap_base(bwrap, size)
    ok, err = _try(base + ["--", "true"])
    if not ok and "--size" in err:
        # bubblewrap < 0.7 (Ubuntu 22.04, Gradescope's base image, has 0.6.1) has no --size: the
        # jail still works, its scratch tmpfs is bounded by the memory limit instead of a size
        size = False
        base = _bwrap_base(bwrap, size)
        ok, err = _try(base + ["--", "true"])
    if not ok:
        why["filesystem"] = f"bubblewrap cannot create namespaces here: {err}"
        why["unprivileged user"] = why["graceful stop"] = "needs bubblewrap"
        return None, version, False, False, False
    signal_reset, err = _try(base + ["--", "env", "--default-signal=INT,TERM", "true"])
    if not signal_reset:
        why["graceful stop"] = f"`env --default-signal` is missing (coreutils >= 8.31): {err}"
    uid_drop = False
    if root:
        setpriv = shutil.which("setpriv")
        if setpriv is None:
            why["unprivileged user"] = "setpriv (util-linux) is not installed"
        else:
            uid = sandbox_uid()
            uid_drop, err = _try(base + ["--cap-add", "CAP_SETUID", "--cap-add", "CAP_SETGID", "--",
                                         setpriv, f"--reuid={uid}", f"--regid={uid}", "--clear-groups",
                                         "--", "true"])
            if not uid_drop:
                why["unprivileged user"] = f"cannot switch to uid {uid} inside bubblewrap: {err}"
    return bwrap, version, uid_drop, signal_reset, size


def _probe_netns(root: bool, why: dict[str, str]) -> bool:
    unshare = shutil.which("unshare")
    if unshare is None:
        why["network"] = "unshare (util-linux) is not installed"
        return False
    user = [] if root else ["--user", "--map-root-user"]
    ok, err = _try([unshare, *user, "--net", "--pid", "--fork", "--kill-child", "--mount-proc", "true"])
    if not ok:
        why["network"] = f"cannot create a network and PID namespace per scenario: {err}"
    return ok


@functools.lru_cache(maxsize=1)
def probe() -> Capabilities:
    """Try every tool once (cached for the life of the process)."""
    root = os.geteuid() == 0
    why: dict[str, str] = {}
    bwrap, version, uid_drop, signal_reset, size = _probe_bwrap(root, why)
    if not root:
        why.setdefault("unprivileged user", "the grader itself runs unprivileged")
    netns = _probe_netns(root, why)
    cgroups = find_cgroup_support()
    if cgroups.problem:
        why["limits"] = cgroups.problem
    return Capabilities(root=root, bwrap=bwrap, bwrap_version=version, bwrap_size=size, uid_drop=uid_drop,
                        signal_reset=signal_reset, netns=netns, cgroups=cgroups, why=why)


@dataclass(frozen=True)
class Protection:
    name: str
    active: bool
    detail: str

    def line(self) -> str:
        return f"{'on ' if self.active else 'OFF'}  {self.name:18} {self.detail}"


def protections(caps: Capabilities | None = None, *, enabled: bool = True) -> list[Protection]:
    """Each protection of student code, and whether it is active (``grader doctor``, results)."""
    caps = caps or probe()
    off = "" if enabled else "sandbox turned off (GRADER_SANDBOX=off)"
    fs = enabled and caps.bwrap is not None
    cg = caps.cgroups
    rows = [
        Protection("filesystem", fs, off or caps.why.get("filesystem") or
                   f"{caps.bwrap_version}: read-only system, own scratch tmpfs"
                   f"{'' if caps.bwrap_size else ' (not size-capped: this bubblewrap has no --size; the memory limit bounds it)'}"
                   "; no outputs, rubric, fixtures, other submissions or grader sources"),
        Protection("network", enabled and caps.netns, off or caps.why.get("network") or
                   "a network namespace per scenario (loopback shared with its sim, recorder, driver)"),
        Protection("processes", enabled and (caps.netns or fs), off or
                   "PID namespaces: ending a scenario ends every process it started, detached ones too"
                   if (caps.netns or fs) else caps.why.get("network", "no PID namespaces")),
        Protection("unprivileged user", enabled and caps.uid_drop, off or caps.why.get("unprivileged user") or
                   f"student code runs as uid {sandbox_uid()}"),
        Protection("memory limit", enabled and cg.memory, off or cg.detail("memory")),
        Protection("process limit", enabled and cg.pids, off or cg.detail("pids")),
        Protection("cpu limit", enabled and cg.cpu, off or cg.detail("cpu")),
        Protection("kill all", enabled and cg.kill, off or cg.detail("kill")),
        Protection("graceful stop", enabled and fs and caps.signal_reset, off or caps.why.get("graceful stop") or
                   "Ctrl-C reaches the student process, not the sandbox around it"),
        Protection("environment", enabled, off or "minimal: ROS variables and the rubric's env, never the caller's"),
        Protection("output cap", enabled, off or "stdout/stderr logs capped per stream, the cut noted in the log"),
    ]
    return rows


def python_roots() -> list[Path]:
    """The interpreter's own trees: the venv and the Python it was made from."""
    roots = {Path(sys.prefix), Path(sys.base_prefix), Path(sys.executable).resolve().parent.parent,
             Path(sys.prefix).resolve(), Path(sys.base_prefix).resolve()}   # a venv reached by a link
    return sorted(roots)
