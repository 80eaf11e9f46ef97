"""Scenarios: run a submission's nodes against the reference simulator while recording a bag.

The parent side (this module) resolves executables against a build and runs each scenario in a
child process (``grader.scenario.run``) with the build's environment and a wall-clock limit.
"""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from grader.errors import GraderError
from grader.scenario.spec import NodeSpec, Scenario, Step

__all__ = ["NodeSpec", "Scenario", "Step", "resolve", "run_scenario", "cancel_all", "CANCELLED"]

#: set by a batch on Ctrl-C: running scenarios are told to stop (their bags get finalized) and
#: no new scenario starts
CANCELLED = threading.Event()
_RUNNING: set[subprocess.Popen] = set()
_RUNNING_LOCK = threading.Lock()


def cancel_all() -> None:
    """Stop every running scenario child (SIGTERM: it unwinds and finalizes its bag)."""
    CANCELLED.set()
    with _RUNNING_LOCK:
        for proc in list(_RUNNING):
            try:
                os.killpg(proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass


def resolve(scenario: Scenario, build) -> Scenario:
    """Fill each node's argv from ``build`` (a BuildResult, or None for grader-only scenarios).

    A node that cannot be resolved (package missing or failed to build, executable missing)
    keeps an ``error`` instead: the scenario still runs, and the items that need that node fail
    with that explanation.
    """
    spec = copy.deepcopy(scenario)
    for node in spec.nodes:
        if build is None:
            node.error = "no build available"
            continue
        try:
            node.argv = build.argv(node.package, node.executable, node.module)
        except GraderError as exc:
            node.error = str(exc)
    spec.prefixes = [str(p) for p in build.prefixes()] if build is not None else []
    return spec


def run_scenario(scenario: Scenario, build, out: Path, *, env: dict[str, str] | None = None) -> dict[str, Any]:
    """Run one scenario in a child process; returns its record (see grader.scenario.run)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    spec = resolve(scenario, build)
    (out / "spec.json").write_text(json.dumps(spec.to_json(), indent=1))
    child_env = env or (build.env() if build is not None else None)
    if child_env is None:
        from grader.rosenv import child_env as make_env
        child_env = make_env()
    limit = spec.time_limit_s + 60.0
    if CANCELLED.is_set():
        raise KeyboardInterrupt
    t0 = time.monotonic()
    with open(out / "scenario.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-m", "grader.scenario.run", str(out / "spec.json"), str(out)],
                                env=child_env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        with _RUNNING_LOCK:
            _RUNNING.add(proc)
        try:
            proc.wait(timeout=limit)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        except BaseException:
            # Ctrl-C in the parent: let the child finalize its bag, then re-raise
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
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
    record_path = out / "scenario.json"
    if record_path.exists():
        record = json.loads(record_path.read_text())
    else:
        tail = (out / "scenario.log").read_text(errors="replace")[-1500:]
        record = {"scenario": spec.id, "steps": [], "processes": {}, "bag": str(out / "bag"),
                  "errors": [f"scenario process ended with code {proc.returncode} without a record:\n{tail}"]}
    record["parent_wall_s"] = round(time.monotonic() - t0, 3)
    return record
