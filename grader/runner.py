"""Process runner for untrusted ROS nodes: one process group each, scripted stdin, limits, logs.

Every scenario starts the simulator, the recorder, the student's nodes and helpers through
:class:`RosGraph`, which leases its own ROS_DOMAIN_ID and guarantees that no process it started
outlives the ``with`` block: stop is SIGINT (what Ctrl-C in a terminal sends, so well-behaved
rclpy nodes shut down cleanly), then SIGTERM, then SIGKILL, always to the whole process group.

A process marked ``untrusted`` (student code) runs in the graph's sandbox when the scenario
has one (:mod:`grader.sandbox`: bubblewrap view, unprivileged user, minimal environment, the
scenario's cgroup) and its stdout/stderr logs are capped.
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
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Sequence, Any

from grader.domain import DomainLease, lease_domain
from grader.errors import GraderError
from grader.rosenv import child_env, trusted_env
from grader.sandbox.capture import CappedLog
from grader.sandbox.jail import Prepared, prepare
from grader.sandbox.scenario import ChildConfig, child_config
from grader.sandbox.watch import LimitWatch
from grader.contracts.process import Limits, StdinLine

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
    untrusted: bool = False                      # student code: the graph's sandbox, capped logs
    pass_fds: tuple[int, ...] = ()               # descriptors this process alone inherits (never untrusted)


def python_argv(module: str, *args: str) -> list[str]:
    """argv that runs ``python -m module args`` with the grader's interpreter."""
    return [sys.executable, "-m", module, *args]


def die_with_parent() -> None:
    """Between fork and exec: the kernel kills this child when the thread that started it ends
    (the grader killed, a batch stopped by Slurm or Gradescope), so nothing it started runs on."""
    if _LIBC is not None:
        _LIBC.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)


def _preexec(spec: "ProcessSpec", prepared: Prepared | None = None) -> None:
    """Runs in the child between fork and exec: new session, die with parent, rlimits, and the
    sandbox's own steps (join the scenario's cgroup)."""
    os.setsid()
    die_with_parent()
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
    if prepared is not None:
        prepared.preexec()


class ManagedProcess:
    """A started process (the leader of its own process group)."""

    #: set before start to hold the stdin script until the event is set (or the timeout passes)
    stdin_gate: threading.Event | None = None
    stdin_gate_timeout_s: float = 20.0

    def __init__(self, spec: ProcessSpec, env: Mapping[str, str], logdir: Path,
                 stdin_gate: threading.Event | None = None, *, prepared: Prepared | None = None,
                 output_cap: int | None = None) -> None:
        self.spec = spec
        self.stdin_gate = stdin_gate
        self.name = spec.name
        self.stdout_path = logdir / f"{spec.name}.stdout.log"
        self.stderr_path = logdir / f"{spec.name}.stderr.log"
        self.timed_out = False
        self.stopped_by_grader = False
        self.killed = False
        self.started_at = time.monotonic()
        self.prepared = prepared
        self.output_cut: dict[str, int] = {}     # stream -> cap, once the log was cut
        self._out = open(self.stdout_path, "wb")
        self._err = open(self.stderr_path, "wb")
        self._capped: list[CappedLog] = []
        stdout: Any = self._out
        stderr: Any = self._err
        pipes: list[tuple[int, int, Path, str]] = []
        if output_cap:
            for path, stream in ((self.stdout_path, "stdout"), (self.stderr_path, "stderr")):
                r, w = os.pipe()
                pipes.append((r, w, path, stream))
            stdout, stderr = pipes[0][1], pipes[1][1]
        argv = prepared.argv if prepared is not None else list(spec.argv)
        try:
            self.popen = subprocess.Popen(
                argv, env=dict(prepared.env if prepared is not None else env),
                cwd=prepared.cwd if prepared is not None else spec.cwd,
                stdin=subprocess.PIPE if spec.stdin is not None else subprocess.DEVNULL,
                stdout=stdout, stderr=stderr,
                preexec_fn=lambda: _preexec(spec, prepared), close_fds=True,
                pass_fds=() if spec.untrusted else spec.pass_fds)
        except OSError as exc:
            self._out.close()
            self._err.close()
            for r, w, _path, _stream in pipes:
                os.close(r)
                os.close(w)
            raise GraderError(f"cannot start {spec.name} ({argv[0]}): {exc.strerror}") from exc
        for r, w, path, stream in pipes:
            os.close(w)
            self._capped.append(CappedLog(r, path, output_cap or 0, stream=stream, on_cut=self._cut))
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

    def on_output_cut(self, stream: str, cap: int) -> None:
        """Hook: called once per stream when its log reached the cap (the scenario reports it)."""

    def _cut(self, stream: str, cap: int) -> None:
        self.output_cut[stream] = cap
        self.on_output_cut(stream, cap)

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
        rc = self.popen.poll()
        return self.prepared.exit_code(rc) if self.prepared is not None else rc

    def alive(self) -> bool:
        return self.popen.poll() is None

    def wait(self, timeout: float | None = None) -> int | None:
        try:
            self.popen.wait(timeout)
        except subprocess.TimeoutExpired:
            return None
        return self.returncode

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
            return self.returncode

    def _close_files(self) -> None:
        for log in self._capped:
            log.join(timeout=2.0)       # EOF once the group is gone; a detached holder ends with the scenario
        for f in (self._out, self._err):
            if not f.closed:
                f.close()
        if self.prepared is not None:
            self.prepared.cleanup()
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

    def __init__(self, workdir: Path, *, prefixes: Iterable[Path] = (), interfaces: Iterable[Path] = (),
                 extra_env: Mapping[str, str] | None = None,
                 lease: DomainLease | None = None, sandbox: ChildConfig | None = None) -> None:
        self.workdir = Path(workdir)
        self.logdir = self.workdir / "logs"
        self.logdir.mkdir(parents=True, exist_ok=True)
        #: the scenario's sandbox for ``untrusted`` processes (from run_scenario), else None
        self.sandbox = sandbox if sandbox is not None else child_config()
        self._lease = lease or lease_domain()
        self.domain_id = self._lease.domain_id
        ros_log = self.workdir / "ros_log"
        extra = {"ROS_LOG_DIR": str(ros_log)}
        if self.sandbox is not None and self.sandbox.netns:
            extra["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"   # the namespace is the boundary
        self._prefixes = [Path(p) for p in prefixes]
        #: the grader's own builds of the students' interface packages (its processes' types)
        self._interfaces = [Path(p) for p in interfaces]
        self.env = child_env(domain_id=self.domain_id, prefixes=self._prefixes, extra={**extra, **(extra_env or {})})
        self.processes: list[ManagedProcess] = []
        self.limits = LimitWatch(self.sandbox)
        self._spawner: ThreadPoolExecutor | None = None
        self._spawner_lock = threading.Lock()

    def start(self, spec: ProcessSpec, process_class: type[ManagedProcess] = ManagedProcess,
              **kwargs) -> ManagedProcess:
        """Start ``spec`` in this graph. From a thread other than the main one, the fork happens
        on the graph's own spawner thread: PR_SET_PDEATHSIG fires when the *thread* that forked
        a child ends, so a process started from a short-lived thread (a launch file's
        TimerAction, measured: SIGKILLed 24 ms after its start) would die with that thread."""
        if threading.current_thread() is threading.main_thread():
            return self._start(spec, process_class, **kwargs)
        with self._spawner_lock:
            if self._spawner is None:
                self._spawner = ThreadPoolExecutor(max_workers=1, thread_name_prefix="graph-spawner")
        return self._spawner.submit(self._start, spec, process_class, **kwargs).result()

    def _start(self, spec: ProcessSpec, process_class: type[ManagedProcess], **kwargs) -> ManagedProcess:
        if any(p.name == spec.name for p in self.processes):
            raise ValueError(f"process name {spec.name!r} already used in this graph")
        env = dict(self.env)
        if spec.untrusted and self.sandbox is not None:
            kwargs["prepared"] = prepare(self.sandbox.jail, spec.argv, env, extra_env=spec.env,
                                         cwd=str(spec.cwd) if spec.cwd else None)
            kwargs["output_cap"] = self.sandbox.policy.output_cap_bytes
        else:
            if spec.env:
                env.update(spec.env)
            if not spec.untrusted:
                # a grader process (the simulator, also when a launch file starts it) runs outside
                # the jail: nothing of the students' Python trees may run in it at start-up
                env = trusted_env(env, self._prefixes, self._interfaces)
        proc = process_class(spec, env, self.logdir, **kwargs)
        if kwargs.get("output_cap"):
            self.limits.watch_output(proc)
        self.processes.append(proc)
        return proc

    def output_cuts(self) -> list[dict]:
        """Every log that reached its cap: ``{"process", "stream", "cap_bytes", "detail"}``."""
        return [{"process": p.name, "stream": stream, "cap_bytes": cap,
                 "detail": f"{p.name}: {stream} cut at {cap / 2**20:g} MiB (output limit)"}
                for p in self.processes for stream, cap in sorted(p.output_cut.items())]

    def stop_all(self) -> None:
        """Stop in reverse start order (student nodes before the recorder and the sim)."""
        for proc in reversed(self.processes):
            proc.stop()

    def close(self) -> None:
        try:
            self.stop_all()
        finally:
            self.limits.stop()
            self._lease.release()
            if self._spawner is not None:
                self._spawner.shutdown(wait=False)

    def __enter__(self) -> "RosGraph":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

