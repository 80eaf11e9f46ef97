"""Process runner for untrusted ROS nodes: one process group each, scripted stdin, limits, logs.

Every scenario starts the simulator, the recorder, the student's nodes and helpers through
:class:`RosGraph`, which leases its own ROS_DOMAIN_ID and guarantees that no process it started
outlives the ``with`` block: stop is SIGINT (what Ctrl-C in a terminal sends, so well-behaved
rclpy nodes shut down cleanly), then SIGTERM, then SIGKILL, always to the whole process group.
"""

from __future__ import annotations

import ctypes
import os
import resource
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping, Sequence

from grader.domain import DomainLease, lease_domain
from grader.errors import GraderError
from grader.rosenv import child_env
from grader.scenario.model import Limits, StdinLine

_PR_SET_PDEATHSIG = 1
try:  # loaded once here: after fork only async-signal-safe work should happen
    _LIBC: ctypes.CDLL | None = ctypes.CDLL("libc.so.6", use_errno=True)
except OSError:
    _LIBC = None


#: limits every student process gets on top of its own ``Limits`` (the rubric's): CPU seconds,
#: address space (rclpy + Fast DDS need about 1 GiB), processes/threads of the user (Linux does
#: not enforce RLIMIT_NPROC for root) and open files
UNTRUSTED = Limits(cpu_s=600, memory_mb=8192)
UNTRUSTED_NPROC = 4096
NOFILE = 1024


@dataclass
class ProcessSpec:
    name: str
    argv: Sequence[str]
    env: Mapping[str, str] | None = None         # extra variables on top of the graph's env
    cwd: Path | None = None
    stdin: Sequence[StdinLine] | None = None     # None: stdin is /dev/null
    close_stdin: bool = False                    # send EOF after the script (a terminal wouldn't)
    limits: Limits = Limits()                    # wall_s, cpu_s, memory_mb (address space)
    nproc: int | None = None                     # RLIMIT_NPROC (see UNTRUSTED_NPROC)
    nofile: int | None = NOFILE
    stop_grace_s: float = 3.0                    # SIGINT -> SIGTERM after this
    term_grace_s: float = 2.0                    # SIGTERM -> SIGKILL after this


def python_argv(module: str, *args: str) -> list[str]:
    """argv that runs ``python -m module args`` with the grader's interpreter."""
    return [sys.executable, "-m", module, *args]


def _preexec(spec: "ProcessSpec") -> None:
    """Runs in the child between fork and exec: new session, die with parent, rlimits."""
    os.setsid()
    if _LIBC is not None:
        _LIBC.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    limits = spec.limits
    pairs = [(resource.RLIMIT_CPU, limits.cpu_s),
             (resource.RLIMIT_AS, limits.memory_mb and limits.memory_mb * 2**20),
             (resource.RLIMIT_NPROC, spec.nproc),
             (resource.RLIMIT_NOFILE, spec.nofile)]
    for res, value in pairs:
        if value:
            soft, hard = resource.getrlimit(res)
            cap = value if hard == resource.RLIM_INFINITY else min(value, hard)
            resource.setrlimit(res, (cap, cap))


class ManagedProcess:
    """A started process (the leader of its own process group)."""

    #: set before start to hold the stdin script until the event is set (or the timeout passes)
    stdin_gate: threading.Event | None = None
    stdin_gate_timeout_s: float = 20.0

    def __init__(self, spec: ProcessSpec, env: Mapping[str, str], logdir: Path,
                 stdin_gate: threading.Event | None = None) -> None:
        self.spec = spec
        self.stdin_gate = stdin_gate
        self.name = spec.name
        self.stdout_path = logdir / f"{spec.name}.stdout.log"
        self.stderr_path = logdir / f"{spec.name}.stderr.log"
        self.timed_out = False
        self.stopped_by_grader = False
        self.killed = False
        self.started_at = time.monotonic()
        self._out = open(self.stdout_path, "wb")
        self._err = open(self.stderr_path, "wb")
        try:
            self.popen = subprocess.Popen(
                list(spec.argv), env=dict(env), cwd=spec.cwd,
                stdin=subprocess.PIPE if spec.stdin is not None else subprocess.DEVNULL,
                stdout=self._out, stderr=self._err,
                preexec_fn=lambda: _preexec(spec), close_fds=True)
        except OSError as exc:
            self._out.close()
            self._err.close()
            raise GraderError(f"cannot start {spec.name} ({spec.argv[0]}): {exc.strerror}") from exc
        self.pid = self.popen.pid
        self.pgid = self.pid
        self._lock = threading.Lock()
        self._threads: list[threading.Thread] = []
        if spec.stdin is not None:
            self._spawn(self._feed_stdin)
        if spec.limits.wall_s:
            self._spawn(self._watchdog)

    # -- background helpers ---------------------------------------------------------------
    def _spawn(self, target) -> None:
        t = threading.Thread(target=target, name=f"{self.name}-{target.__name__}", daemon=True)
        t.start()
        self._threads.append(t)

    def _feed_stdin(self) -> None:
        pipe = self.popen.stdin
        assert pipe is not None
        if self.stdin_gate is not None:
            # e.g. "the node is up and its topics are recorded": a person types after the prompt
            self.stdin_gate.wait(timeout=self.stdin_gate_timeout_s)
        try:
            for line in self.spec.stdin or ():
                if self.pause_before_line(line.delay):
                    return
                pipe.write((line.line + "\n").encode())
                pipe.flush()
                self.on_stdin_line(line.line)
            if self.spec.close_stdin:
                pipe.close()
        except (BrokenPipeError, ValueError, OSError):
            pass  # the process exited or closed stdin: nothing more to type

    def on_stdin_line(self, text: str) -> None:
        """Hook: called after each scripted line is written (scenario driver records it)."""

    def pause_before_line(self, seconds: float) -> bool:
        """Hook: wait a scripted line's delay; True when the process exited meanwhile (the
        scenario waits in simulated time when it runs faster than real time)."""
        return self._sleep_unless_exited(seconds)

    def _sleep_unless_exited(self, seconds: float) -> bool:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if self.popen.poll() is not None:
                return True
            time.sleep(min(0.02, max(0.0, deadline - time.monotonic())))
        return self.popen.poll() is not None

    def _watchdog(self) -> None:
        assert self.spec.limits.wall_s
        if not self._sleep_unless_exited(self.spec.limits.wall_s):
            self.timed_out = True
            self.stop()

    # -- public API -----------------------------------------------------------------------
    @property
    def returncode(self) -> int | None:
        return self.popen.poll()

    def alive(self) -> bool:
        return self.popen.poll() is None

    def wait(self, timeout: float | None = None) -> int | None:
        try:
            return self.popen.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def _signal_group(self, sig: int) -> None:
        try:
            os.killpg(self.pgid, sig)
        except ProcessLookupError:
            pass

    def stop(self, grace_s: float | None = None) -> int | None:
        """SIGINT, then SIGTERM, then SIGKILL to the whole group; returns the exit code.

        The group is killed even after the leader exited, so grandchildren go too.
        """
        with self._lock:
            grace = self.spec.stop_grace_s if grace_s is None else grace_s
            if self.alive():
                self.stopped_by_grader = True
                for sig, wait_s in ((signal.SIGINT, grace), (signal.SIGTERM, self.spec.term_grace_s)):
                    self._signal_group(sig)
                    if self.wait(wait_s) is not None:
                        break
                else:
                    self.killed = True
                    self._signal_group(signal.SIGKILL)
                    self.popen.wait()
            self._signal_group(signal.SIGKILL)  # stragglers left in the group
            self._close_files()
            return self.popen.returncode

    def _close_files(self) -> None:
        for f in (self._out, self._err):
            if not f.closed:
                f.close()
        if self.popen.stdin and not self.popen.stdin.closed:
            try:
                self.popen.stdin.close()
            except OSError:
                pass

    def output(self) -> str:
        """Everything the process printed to stdout so far."""
        if not self._out.closed:
            self._out.flush()
        return self.stdout_path.read_text(errors="replace")

    def errors(self) -> str:
        if not self._err.closed:
            self._err.flush()
        return self.stderr_path.read_text(errors="replace")

    def __repr__(self) -> str:
        return f"<ManagedProcess {self.name} pid={self.pid} rc={self.returncode}>"


class RosGraph:
    """An isolated ROS graph: a leased domain id, localhost-only discovery, owned processes."""

    def __init__(self, workdir: Path, *, prefixes: Iterable[Path] = (),
                 extra_env: Mapping[str, str] | None = None,
                 lease: DomainLease | None = None) -> None:
        self.workdir = Path(workdir)
        self.logdir = self.workdir / "logs"
        self.logdir.mkdir(parents=True, exist_ok=True)
        self._lease = lease or lease_domain()
        self.domain_id = self._lease.domain_id
        ros_log = self.workdir / "ros_log"
        self.env = child_env(domain_id=self.domain_id, prefixes=prefixes,
                             extra={"ROS_LOG_DIR": str(ros_log), **(extra_env or {})})
        self.processes: list[ManagedProcess] = []

    def start(self, spec: ProcessSpec, process_class: type[ManagedProcess] = ManagedProcess,
              **kwargs) -> ManagedProcess:
        if any(p.name == spec.name for p in self.processes):
            raise ValueError(f"process name {spec.name!r} already used in this graph")
        env = dict(self.env)
        if spec.env:
            env.update(spec.env)
        proc = process_class(spec, env, self.logdir, **kwargs)
        self.processes.append(proc)
        return proc

    def stop_all(self) -> None:
        """Stop in reverse start order (student nodes before the recorder and the sim)."""
        for proc in reversed(self.processes):
            proc.stop()

    def close(self) -> None:
        try:
            self.stop_all()
        finally:
            self._lease.release()

    def __enter__(self) -> "RosGraph":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
