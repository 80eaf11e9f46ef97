"""One-shot student code outside a scenario: the colcon build, ``setup.py``, a launch file.

They run student code too (``setup.py``, ``CMakeLists.txt``, ``generate_launch_description``),
so they get the same jail as a student node: a read-only view with write access only to what
they must write (a build's ``build/``, ``install/``, ``log/``), no network at all (a loopback
of their own), an unprivileged user, a cgroup with memory and process limits that is killed
whole at the end or on timeout, and capped output.
"""

from __future__ import annotations

import tempfile
import os
import signal
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence, cast

from grader.sandbox import cgroups
from grader.sandbox.capture import CappedLog
from grader.sandbox.jail import Jail, prepare, ros_roots
from grader.sandbox.probe import probe
from grader.sandbox.scenario import SandboxPolicy, require_complete, sandbox_mode, student_jail

_SEQ = iter(range(1, 1 << 62))


@dataclass
class JailedRun:
    returncode: int | None
    timed_out: bool = False
    sandboxed: bool = False
    limits_hit: list[str] = field(default_factory=list)
    left_running: int = 0


def hand_over(paths: Sequence[Path], uid: int | None) -> None:
    """Make the directories a jailed command must write owned by its (unprivileged) user."""
    for p in paths:
        p.mkdir(parents=True, exist_ok=True)
        if uid is not None:
            os.chown(p, uid, uid)


def take_back(paths: Sequence[Path]) -> None:
    """Give what the jailed command wrote back to the grader's user (root), so no other process
    of that unprivileged uid can change a cached build later."""
    me, group = os.getuid(), os.getgid()
    for top in paths:
        if not top.exists():
            continue
        for dirpath, dirnames, filenames in os.walk(top):
            for name in [*dirnames, *filenames]:
                os.lchown(os.path.join(dirpath, name), me, group)
        os.lchown(top, me, group)


def run_jailed(argv: Sequence[str], *, env: Mapping[str, str], cwd: Path, stdout: Path,
               stderr: Path | None = None, ro: Sequence[Path] = (), rw: Sequence[Path] = (),
               python_path: Sequence[Path] = (), timeout_s: float, memory_mb: int, pids: int = 1024,
               output_cap: int = 50 * 2**20, name: str = "oneshot") -> JailedRun:
    """Run ``argv`` in a jail (no network) and wait; ``stdout``/``stderr`` are log files (capped;
    ``stderr=None`` sends both streams to ``stdout``). On timeout everything it started is killed.
    With ``GRADER_SANDBOX=off`` (or no bubblewrap) it runs unsandboxed, as before."""
    mode = sandbox_mode()
    caps = probe()
    require_complete(caps)
    group: cgroups.CgroupSet | None = None
    jail: Jail | None = None
    if mode != "off":
        if caps.cgroups.bases:
            group = cgroups.CgroupSet.create(caps.cgroups, f"grader-{os.getpid()}-{next(_SEQ)}-{name}")
            group.set_limits(memory_bytes=memory_mb * 2**20, pids=pids)
        policy = SandboxPolicy.from_env()
        jail = student_jail(caps, policy, ro=[*(str(p) for p in ro), *ros_roots(env)],
                            rw=[str(p) for p in rw], own_network=True, cgroup=group)
        if python_path:
            jail = Jail.from_json({**jail.to_json(), "python_path": [str(p) for p in python_path]})
    if jail is not None and jail.bwrap:
        hand_over([Path(p) for p in rw], jail.uid)
    prepared = prepare(jail, argv, env, cwd=str(cwd))
    if not prepared.sandboxed:
        prepared.cwd = str(cwd)
    result = JailedRun(returncode=None, sandboxed=prepared.sandboxed)
    pipes = [os.pipe() for _ in range(1 if stderr is None else 2)]
    try:
        proc = subprocess.Popen(prepared.argv, env=prepared.env, cwd=prepared.cwd, stdin=subprocess.DEVNULL,
                                stdout=pipes[0][1], stderr=pipes[-1][1], start_new_session=True,
                                preexec_fn=prepared.preexec)
    except OSError:
        for r, w in pipes:
            os.close(r)
            os.close(w)
        prepared.cleanup()
        if group is not None:
            group.remove()
        raise
    logs: list[CappedLog] = []
    for (r, w), path, stream in zip(pipes, [stdout, stderr], ["output", "stderr"]):
        os.close(w)
        logs.append(CappedLog(r, cast(Path, path), output_cap, stream=stream))   # (a pipe per log file)
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        result.timed_out = True
    finally:
        _end(proc, group, result, memory_mb, pids)
        for log in logs:
            log.join(timeout=5.0)
        result.returncode = prepared.exit_code(proc.returncode)
        prepared.cleanup()
        if jail is not None and jail.bwrap and jail.uid is not None:
            take_back([Path(p) for p in rw])
    result.limits_hit += [f"{log.stream} cut at {output_cap / 2**20:g} MiB" for log in logs if log.cut]
    return result


def _end(proc: subprocess.Popen, group: cgroups.CgroupSet | None, result: JailedRun,
         memory_mb: int, pids: int) -> None:
    """Kill whatever is left: the process group, then (detached ones too) the cgroup."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait()
    if group is None:
        return
    try:
        result.left_running = group.kill()
        counts = group.counters()
        if counts.get("oom_kills"):
            result.limits_hit.append(f"memory limit of {memory_mb} MiB reached: the kernel killed "
                                     f"{int(counts['oom_kills'])} process(es)")
        if counts.get("forks_refused"):
            result.limits_hit.append(f"process limit of {pids} processes/threads reached: "
                                     f"{int(counts['forks_refused'])} fork(s) refused")
    finally:
        group.remove()


def run_jailed_capture(argv: Sequence[str], *, cap: int = 4 * 2**20, **kwargs) -> tuple[JailedRun, str, str]:
    """:func:`run_jailed`, returning what it printed (at most ``cap`` bytes per stream)."""
    with tempfile.TemporaryDirectory(prefix="grader-oneshot-") as tmp:
        out, err = Path(tmp) / "stdout", Path(tmp) / "stderr"
        run = run_jailed(argv, stdout=out, stderr=err, output_cap=cap, **kwargs)
        return run, out.read_text(errors="replace"), err.read_text(errors="replace")


def build_trees(env: Mapping[str, str]) -> list[Path]:
    """The ``install`` and ``src`` trees of the builds on ``env``'s ``AMENT_PREFIX_PATH``
    (``<build>/install/<pkg>`` entries), for a jail that runs a launch file or setup.py."""
    trees: list[Path] = []
    for entry in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        p = Path(entry)
        if entry and p.parent.name == "install":
            for tree in (p.parent, p.parent.parent / "src"):
                if tree.is_dir() and tree not in trees:
                    trees.append(tree)
    return trees
