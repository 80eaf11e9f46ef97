"""Scenarios: run a submission's nodes against the reference simulator while recording a bag.

The parent side (this module) resolves a rubric scenario against a build (:func:`resolve`: the
argv of every process, a launch file's nodes) into a :class:`~grader.scenario.runspec.ScenarioRun`
and runs it in a child process (``grader.scenario.run``) with the build's environment and a
wall-clock limit.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from grader.contracts.scenario_record import ScenarioRecord
from grader.contracts.output_folder import RUN_JSON, SCENARIO_JSON
from grader.errors import GraderError
from grader.scenario.model import Scenario
from grader.scenario.runspec import LaunchedProcess, PackageFacts, ScenarioRun

__all__ = ["Scenario", "ScenarioRun", "resolve", "run_scenario", "cancel_all", "CANCELLED", "children_cpu_s"]

#: set by a batch on Ctrl-C: running scenarios are told to stop (their bags get finalized) and
#: no new scenario starts
CANCELLED = threading.Event()
_RUNNING: set[subprocess.Popen] = set()
_RUNNING_LOCK = threading.Lock()
#: how long the child may outlive the scenario's own limit (bag finalisation, stops)
GRACE_S = 60.0
#: the CPU seconds of the scenario children this thread has reaped (:func:`children_cpu_s`)
_REAPED = threading.local()


def children_cpu_s() -> float:
    """CPU seconds of every scenario child this thread ran, so far: each child's own and its
    reaped descendants' (the simulator, the students' processes, their sandbox wrappers), as
    ``wait4`` reports them. A submission's scenario runs in a thread of its own with its
    retries, so the difference around it is that scenario's CPU. A process that left the tree
    (a daemon the sandbox killed) is not counted."""
    return float(getattr(_REAPED, "cpu_s", 0.0))


def _wait(proc: subprocess.Popen, timeout: float | None) -> None:
    """``proc.wait(timeout)``, reaping with ``wait4`` to count the child's CPU."""
    end = None if timeout is None else time.monotonic() + timeout
    delay = 0.005
    while proc.returncode is None:
        try:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        except ChildProcessError:         # reaped elsewhere: its CPU is unknown
            proc.wait(timeout=0)
            return
        if pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            _REAPED.cpu_s = children_cpu_s() + usage.ru_utime + usage.ru_stime
            return
        if end is not None and time.monotonic() >= end:
            raise subprocess.TimeoutExpired(proc.args, timeout or 0.0)
        time.sleep(delay)
        delay = min(0.05, delay * 2)


def cancel_all() -> None:
    """Stop every running scenario child (SIGTERM: it unwinds and finalizes its bag)."""
    CANCELLED.set()
    with _RUNNING_LOCK:
        for proc in list(_RUNNING):
            try:
                os.killpg(proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass


def resolve(scenario_id: str, scenario: Scenario, build: Any) -> ScenarioRun:
    """What the child needs besides the scenario: each process's argv from ``build`` (a
    BuildResult, or None for grader-only scenarios), a launch file's nodes, install prefixes.

    A process that cannot be resolved (package missing or failed to build, executable missing,
    broken launch file) keeps an ``error`` instead: the scenario still runs, and the items that
    need that process fail with that explanation.
    """
    from grader.launch import launch_files, resolve_launch  # noqa: PLC0415 - at the head it would close a circle: scenario -> launch -> scenario

    launched: dict[str, tuple[LaunchedProcess, ...]] = {}
    sim_node = "turtlesim"
    notes: dict[str, tuple[str, ...]] = {}
    installed: dict[str, bool] = {}
    files: dict[str, str] = {}
    for proc in scenario.processes:
        if build is None:
            launched[proc.name] = (LaunchedProcess(name=proc.name, process=proc.name, error="no build available"),)
            continue
        if proc.launch:
            result = resolve_launch(proc, build, sim_in_scenario=scenario.sim)
            launched[proc.name] = tuple(result.processes)
            sim_node = result.sim_node or sim_node
            notes[proc.name] = tuple(result.notes)
            installed[proc.name] = result.installed
            if result.file:
                files[proc.name] = result.file
            continue
        try:
            argv = build.argv(proc.package, proc.executable, proc.module) + proc.ros_args()
            launched[proc.name] = (LaunchedProcess(name=proc.name, process=proc.name, argv=tuple(argv)),)
        except GraderError as exc:
            launched[proc.name] = (LaunchedProcess(name=proc.name, process=proc.name, error=str(exc)),)
    prefixes = tuple(str(p) for p in build.prefixes()) if build is not None else ()
    interfaces = tuple(str(p) for p in build.interface_prefixes()) if build is not None else ()
    from grader.workspace.executables import stray_executables  # noqa: PLC0415 - scenario loads in every scenario child process; workspace.executables only on this path

    packages = {name: PackageFacts(status=pkg.status, executables=tuple(sorted(pkg.executables)),
                                   launch_files=tuple(launch_files(build, name)),
                                   stray_executables=tuple(stray_executables(name, build.install / name)))
                for name, pkg in (build.packages.items() if build is not None else ())}
    return ScenarioRun(id=scenario_id, scenario=scenario, launched=launched, prefixes=prefixes,
                       interfaces=interfaces,
                       sim_node=sim_node, notes=notes, launch_installed=installed, packages=packages,
                       launch_files=files)


#: how long a scenario child stopped by SIGTERM gets to stop its processes and finalize its bag
TERMINATE_WAIT_S = 40.0


def run_scenario(run: ScenarioRun, out: Path, *, env: dict[str, str] | None = None) -> ScenarioRecord:
    """Run one resolved scenario in a child process; returns its record (see grader.scenario.run)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    run_file = out / RUN_JSON
    run_file.write_text(run.model_dump_json(indent=1))
    if env is None:
        from grader.rosenv import child_env  # noqa: PLC0415 - scenario loads in every scenario child process; rosenv only on this path
        env = child_env(prefixes=[Path(p) for p in run.prefixes])
    limit = run.wall_limit_s + GRACE_S
    if CANCELLED.is_set():
        raise KeyboardInterrupt
    t0 = time.monotonic()
    from grader.runner import die_with_parent      # (grader.runner imports this package's model)  # noqa: PLC0415 - scenario loads in every scenario child process; runner only on this path
    from grader.sandbox import ScenarioSandbox     # namespaces + cgroups; see grader/sandbox  # noqa: PLC0415 - scenario loads in every scenario child process; sandbox only on this path

    sandbox = ScenarioSandbox(prefixes=run.prefixes, env=env, memory_mb=run.scenario.limits.memory_mb,
                              name=run.id)
    from grader.rosenv import trusted_env     # nothing of the students' builds runs in the grader's processes  # noqa: PLC0415 - scenario loads in every scenario child process; rosenv only on this path

    env = trusted_env(env, [Path(p) for p in run.prefixes], [Path(p) for p in run.interfaces])
    with sandbox, open(out / "scenario.log", "wb") as log:
        argv = sandbox.argv([sys.executable, "-m", "grader.scenario.run", str(run_file), str(out)])
        # a grader killed outright (SIGKILL, a scheduler's limit) takes its scenarios with it: they
        # ran on for up to their wall limit otherwise (a lockstep drive: 1000 s), beside the next batch
        proc = subprocess.Popen(argv, env=sandbox.env(env), stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True, preexec_fn=die_with_parent)
        with _RUNNING_LOCK:
            _RUNNING.add(proc)
        try:
            _wait(proc, limit)
        except subprocess.TimeoutExpired:
            _terminate(proc)
        except BaseException:
            _terminate(proc)          # Ctrl-C in the parent: let the child finalize its bag
            raise
        finally:
            with _RUNNING_LOCK:
                _RUNNING.discard(proc)
            try:
                os.killpg(proc.pid, signal.SIGKILL)   # anything left in the group
            except ProcessLookupError:
                pass
    if CANCELLED.is_set():
        raise KeyboardInterrupt
    record_path = out / SCENARIO_JSON
    try:
        record = ScenarioRecord.read(record_path)
    except (OSError, ValueError) as exc:       # none (killed before it wrote one), or cut short
        tail = (out / "scenario.log").read_text(errors="replace")[-1500:]
        what = "a record" if isinstance(exc, FileNotFoundError) else f"a readable record ({exc})"
        record = ScenarioRecord(scenario=run.id, steps=[], processes={}, bag=str(out / "bag"),
                                errors=[f"scenario process ended with code {proc.returncode} without {what}:\n{tail}"])
    report = sandbox.report(record.to_json())
    record = record.amended({"sandbox": report, "limits_hit": [hit["detail"] for hit in report["limits_hit"]],
                             "parent_wall_s": round(time.monotonic() - t0, 3)}, str(record_path))
    record.write(record_path)
    return record


def _terminate(proc: subprocess.Popen) -> None:
    os.killpg(proc.pid, signal.SIGTERM)
    try:
        # its students stop one after the other (up to 3 s each), then the recorder finalizes
        _wait(proc, TERMINATE_WAIT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        _wait(proc, None)
