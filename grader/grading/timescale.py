"""``--time-scale K``: run a submission's scenarios K times faster than real time, when it is safe.

The simulator owns simulated time (:mod:`grader.sim.clock`) and every node runs with
``use_sim_time``, so a scenario's motion and every ROS timer are those of a 1x run, K times
sooner. What does not follow ``/clock`` is the wall clock: a node that paces itself with
``time.sleep`` or reads ``time.time()`` would behave differently, and its grade would depend on
the speed. So a scenario only runs faster when

0. its rubric does not pin it to real time (``real_time: true``, for a scenario that judges
   wall-clock behaviour), and
1. the static scan of the Python packages it runs (their installed modules) finds no wall-clock
   pacing (:data:`WALL_CLOCK`) and no executor that cannot keep pace with ``/clock``
   (:data:`BUSY_ON_SIM_TIME`), and
2. at run time the watchdog (:mod:`grader.scenario.watchdog`) sees every rate the rubric expects
   kept in simulated time, nobody else publishes ``/clock``, and the run itself worked.

Otherwise the scenario runs (again) at 1x, and its record says why: ``scenario.json`` and
result.json carry ``time_scale: {requested, used, fallback}`` per scenario; the report and
``grader check`` print it. The default speed is :data:`grader.contracts.speed.DEFAULT_TIME_SCALE`.
"""

from __future__ import annotations

import ast
import functools
import shutil
import sys
from pathlib import Path
from typing import Any, Iterable

from grader.contracts.output_folder import SCENARIO_JSON
from grader.contracts.scenario_record import ScenarioRecord
from grader import rclpy_fix
from grader.grading.scenario_packages import packages_run, workspace_packages
from grader.grading.starvation import starvation
from grader.rosenv import PY_SITE
from grader.sandbox import allotment
from grader.contracts.speed import default_time_scale
from grader.workspace.executables import executable_paths, is_python_script
from grader.scenario.runspec import RateExpectation, ScenarioRun
from grader.scenario import run_scenario

#: calls (and attributes) that read or wait on the wall clock; a node using any of them is not
#: run faster than real time
WALL_CLOCK = frozenset({
    "time.sleep", "time.time", "time.time_ns", "time.monotonic", "time.monotonic_ns",
    "time.perf_counter", "time.perf_counter_ns", "time.clock_gettime", "time.clock_gettime_ns",
    "datetime.datetime.now", "datetime.datetime.utcnow", "datetime.datetime.today",
    "datetime.date.today", "threading.Timer", "asyncio.sleep",
})
#: executors that take a whole CPU core once ``/clock`` arrives, so their node falls behind
#: simulated time: rclpy 7.1.6's MultiThreadedExecutor (ros2/rclpy issue 1452; measured by
#: ``benchmarks/bench_executor.py``: 1.01-1.03 CPU s/s idle next to the simulator at 2x, against
#: 0.05-0.08 at 1x and 0.06-0.09 on the SingleThreadedExecutor at 2x). The run-time watchdog's
#: busy signal (:mod:`grader.scenario.watchdog`) samples CPU between steps and can miss a short
#: scenario. On an rclpy with the upstream fix, or with the grader's own (:mod:`grader.rclpy_fix`),
#: the bench shows ``multi`` near ``single``: :func:`executor_busy_loops` then lets it run faster.
BUSY_ON_SIM_TIME = frozenset({"rclpy.executors.MultiThreadedExecutor"})
#: an rclpy clock that is not the node's ROS clock (a timer on it ignores ``/clock``)
WALL_CLOCK_TYPES = ("ClockType.STEADY_TIME", "ClockType.SYSTEM_TIME")
#: the analyzer whose expectations the watchdog checks
RATE_ANALYZER = "publish_rate"
#: why a scenario marked ``real_time: true`` in its rubric runs at 1x
REAL_TIME = "the rubric runs this scenario in real time (real_time: true)"


def _dotted(node: ast.AST) -> str | None:
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return ".".join(reversed(parts))
    return None


def scan_source(text: str) -> list[tuple[int, str]]:
    """``(line, what)`` for every wall-clock use (and every :data:`BUSY_ON_SIM_TIME` executor)
    in Python source (imports resolved: ``import time as t``, ``from time import sleep``, ``from
    datetime import datetime``)."""
    try:
        tree = ast.parse(text)
    except (SyntaxError, ValueError):
        return []
    names: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                names[(a.asname or a.name).split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom) and node.module:
            for a in node.names:
                names[a.asname or a.name] = f"{node.module}.{a.name}"
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            dotted = _dotted(node.func)
            if dotted is None:
                continue
            head, _, rest = dotted.partition(".")
            full = names.get(head, head) + (f".{rest}" if rest else "")
            if full in WALL_CLOCK or full in BUSY_ON_SIM_TIME:
                found.append((node.lineno, f"{full}()"))
        elif isinstance(node, ast.Attribute):
            dotted = _dotted(node)
            if dotted and dotted.endswith(WALL_CLOCK_TYPES):
                found.append((node.lineno, dotted))
    return sorted(set(found))


def package_files(build: Any, package: str) -> list[Path]:
    """The installed Python code of a built package: its modules (what its nodes import) and its
    Python executables in ``lib/<package>/`` (e.g. ``install(PROGRAMS)`` scripts, found as
    ``ros2 run`` finds them)."""
    pkg = getattr(build, "packages", {}).get(package)
    if pkg is None or pkg.status != "built":
        return []
    prefix = Path(build.install) / package
    site = prefix / PY_SITE
    modules = sorted(site.rglob("*.py")) if site.is_dir() else []
    return modules + [p for p in executable_paths(package, prefix) if is_python_script(p)]


def scan_packages(build: Any, packages: Iterable[str]) -> list[str]:
    """``package/module.py:LINE: call`` (``lib/package/script:LINE: call`` for an executable
    script) for every wall-clock use in the packages' Python code."""
    hits: list[str] = []
    for package in sorted(packages):
        prefix = Path(build.install) / package
        site = prefix / PY_SITE
        for path in package_files(build, package):
            text = path.read_text(errors="replace")
            shown = path.relative_to(site) if path.is_relative_to(site) else path.relative_to(prefix)
            for line, what in scan_source(text):
                hits.append(f"{shown}:{line}: {what}")
    return hits


def pacing_reason(build: Any, run: ScenarioRun, *, lockstep: bool = False) -> str | None:
    """Why the scenario's packages cannot run on simulated time (the static scan), or None.
    ``lockstep``: an executor of ``BUSY_ON_SIM_TIME`` is no reason there. Its busy loop lasts as
    long as ``/clock`` keeps coming, which in lockstep is one message per tick, after which it
    rests like any other node; one that does not is caught at run time (the tick's quiet wait,
    :mod:`grader.scenario.lockstep`)."""

    if build is None:
        return None
    packages = packages_run(run.scenario, workspace_packages(Path(build.root) / "src"))
    hits = scan_packages(build, packages)
    busy = [h for h in hits if h.rsplit(": ", 1)[1].removesuffix("()") in BUSY_ON_SIM_TIME]
    pacing = [h for h in hits if h not in busy]
    if lockstep or (busy and not executor_busy_loops()):
        busy = []
    reasons = []
    if pacing:
        more = f" and {len(pacing) - 3} more" if len(pacing) > 3 else ""
        reasons.append("wall-clock pacing in node code (" + "; ".join(pacing[:3]) + more +
                       "): ROS timers and create_rate follow simulated time, these do not")
    if busy:
        reasons.append(f"{busy[0]}: rclpy's MultiThreadedExecutor takes a whole CPU core once /clock "
                       "arrives (ros2/rclpy issue 1452), so its node would fall behind simulated time")
    return "; ".join(reasons) or None


@functools.cache
def executor_busy_loops() -> bool:
    """Whether the rclpy that student nodes run with (this interpreter's) still has the
    MultiThreadedExecutor busy loop: not once ``grader setup`` fixed it (:mod:`grader.rclpy_fix`;
    ``bench_executor.py``: idle on ``/clock`` 1.02 -> 0.13 CPU s/s), nor on an rclpy with the
    upstream fix. Probed once per process, and only when a scan finds the executor; a probe
    that fails counts as busy."""
    return rclpy_fix.state(sys.executable)[0] in ("busy", "unknown")


def expected_rates(rubric: Any, scenario_id: str) -> tuple[RateExpectation, ...]:
    """The publish rates the rubric's items expect on a scenario (the watchdog's reference)."""
    from grader import analyze  # noqa: PLC0415 - analyze loads pandas, numpy (424 ms CPU), only on this path

    out: list[RateExpectation] = []
    for item in rubric.items:
        if item.analyzer != RATE_ANALYZER or scenario_id not in item.scenario:
            continue
        params = analyze.effective_params(RATE_ANALYZER, item.params)
        try:
            out.append(RateExpectation(topic=params["topic"], expected_hz=float(params["expected_hz"]),
                                       rel_tol=float(params.get("partial_rel_tol") or 0.3)))
        except (KeyError, TypeError, ValueError):
            continue
    return tuple(dict.fromkeys(out))


def run_at_scale(run: ScenarioRun, folder: Path, time_scale: float, build: Any,
                 rates: tuple[RateExpectation, ...] = ()) -> ScenarioRecord:
    """Run the scenario at ``time_scale`` when the scan allows it, else (or when the run says it
    would not grade like 1x) at 1x; the record's ``time_scale`` says which and why."""
    if run.scenario.lockstep:
        return run_lockstep(run, folder, build)
    if time_scale <= 1:
        return run_scenario(run, folder)
    reason = REAL_TIME if run.scenario.real_time else pacing_reason(build, run)
    attempt: dict[str, Any] = {}
    if reason is None:
        record = run_scenario(run.model_copy(update={"time_scale": time_scale, "expected_rates": rates}),
                              folder)
        ts = record.time_scale.to_json() if record.time_scale is not None else {}
        reason = record.time_scale.fallback if record.time_scale is not None else None
        if reason is None and record.errors:
            reason = "the run on simulated time failed: " + str(record.errors[0]).splitlines()[0]
        if reason is None:
            reason = too_busy_for(record, time_scale)
        if reason is None:
            return _note(folder, record, {**ts, "requested": time_scale})
        attempt = {"attempt_wall_s": record.parent_wall_s}
        shutil.rmtree(folder, ignore_errors=True)
    record = _with_attempt(run_scenario(run, folder), attempt)
    return _note(folder, record, {"requested": time_scale, "used": 1.0, "fallback": reason, **attempt})


def machine_time_scale(requested: float | None = None) -> float:
    """The speed scenarios run at: ``requested``, else the default for the CPUs this grader is
    given (its cgroup's quota in a container): :func:`grader.contracts.speed.default_time_scale`."""
    return default_time_scale(allotment.current().cpus) if requested is None else requested


def too_busy_for(record: ScenarioRecord, time_scale: float) -> str | None:
    """Why a run at ``time_scale`` starved (``grader.grading.starvation``, not by the student's
    own processes) goes again at 1x, or None. At K x every process wakes K times as often per
    wall second, so the same machine starves it sooner (a make test's fixture batch beside the
    rest of the suite: Lab 3's no_wrap controller scenario, its simulator waiting 0.54 s per
    second at 4x, in its first recording and in its re-run); at 1x it needs a K-th of the CPU."""
    found = starvation(record)
    if found is None or found.own:
        return None
    return f"{TOO_BUSY}{time_scale:g}x ({found.reason})"


#: how :func:`too_busy_for`'s reasons begin (a retry stays at 1x after one)
TOO_BUSY = "the grading machine was too busy for "


class ScaledRecording:
    """:func:`run_at_scale` as the starvation retries call it (``record_unstarved``): once the
    machine was too busy for K x, the retries run at 1x at once, and keep saying why. (Each
    retry tried 4x again in Gradescope's 0.5-CPU container, starved, and ran at 1x after it: two
    recordings per attempt.)"""

    def __init__(self, run: ScenarioRun, folder: Path, time_scale: float, build: Any,
                 rates: tuple[RateExpectation, ...] = ()) -> None:
        self.run, self.folder, self.time_scale, self.build, self.rates = run, folder, time_scale, build, rates
        self.busy_note: dict[str, Any] | None = None

    def __call__(self) -> ScenarioRecord:
        if self.busy_note is not None and not self.run.scenario.lockstep:
            return _note(self.folder, run_at_scale(self.run, self.folder, 1.0, self.build), self.busy_note)
        record = run_at_scale(self.run, self.folder, self.time_scale, self.build, self.rates)
        ts = record.time_scale.to_json() if record.time_scale is not None else {}
        if str(ts.get("fallback") or "").startswith(TOO_BUSY):
            self.busy_note = {k: v for k, v in ts.items() if k != "attempt_wall_s"}
        return record


def run_lockstep(run: ScenarioRun, folder: Path, build: Any) -> ScenarioRecord:
    """A scenario marked ``lockstep: true``: on the simulator's lockstep clock when the scan
    allows it (the same rule as a time scale: nodes paced by ROS time only), else, or when the
    lockstep run could not go on, on the wall clock; the record's ``lockstep`` says which and why
    (``--time-scale`` does not apply: lockstep runs as fast as the nodes allow)."""
    reason = pacing_reason(build, run, lockstep=True)
    attempt: dict[str, Any] = {}
    if reason is None:
        record = run_scenario(run.model_copy(update={"lockstep": True}), folder)
        ls = record.lockstep.to_json() if record.lockstep is not None else {}
        reason = record.lockstep.fallback if record.lockstep is not None else None
        if reason is None and record.errors:
            reason = "the lockstep run failed: " + str(record.errors[0]).splitlines()[0]
        if reason is None:
            return record
        attempt = {"attempt_wall_s": record.parent_wall_s, "attempt": ls}
        shutil.rmtree(folder, ignore_errors=True)
    record = _with_attempt(run_scenario(run.model_copy(update={"lockstep": False}), folder), attempt)
    return _note(folder, record, {"used": False, "fallback": reason, **attempt}, key="lockstep")


def _with_attempt(record: ScenarioRecord, attempt: dict[str, Any]) -> ScenarioRecord:
    """The 1x record with the wall time of the attempt before it added (in memory: the file keeps
    its own run's, and the attempt's in its ``time_scale`` or ``lockstep`` note)."""
    if attempt.get("attempt_wall_s") is None:
        return record
    return record.amended({"parent_wall_s": round((record.parent_wall_s or 0.0) + attempt["attempt_wall_s"], 3)})


def _note(folder: Path, record: ScenarioRecord, time_scale: dict[str, Any],
          key: str = "time_scale") -> ScenarioRecord:
    """Keep the decision in the record and in scenario.json (a reuse or a regrade reads it)."""
    ScenarioRecord.amend(Path(folder) / SCENARIO_JSON, {key: time_scale})
    return record.amended({key: time_scale})


def describe(scenario_id: str, ts: dict[str, Any]) -> str:
    """One line for the report and ``grader check``."""
    requested = float(ts.get("requested", 1.0))
    used = float(ts.get("used", 1.0))
    if used > 1:
        return f"scenario {scenario_id} ran {used:g}x faster than real time (on simulated time)"
    return f"scenario {scenario_id} ran at 1x instead of {requested:g}x: {ts.get('fallback', 'no reason recorded')}"


def describe_lockstep(scenario_id: str, ls: dict[str, Any]) -> str:
    """One line for the report and ``grader check`` on a scenario the rubric runs in lockstep."""
    if not ls.get("used"):
        return (f"scenario {scenario_id} ran on the wall clock instead of lockstep simulated time: "
                f"{ls.get('fallback', 'no reason recorded')}")
    quiet = int(ls.get("quiet_timeouts") or 0)
    cuts = int(ls.get("wall_cuts") or 0)
    # not "exactly" without a condition: a node that sends before DDS has matched its peer (a
    # service call without waiting for the service) races discovery in every run (chase's
    # bench_flake class: one such /spawn request answered in one run of three)
    how = ("every tick quiet: the same code repeats it exactly, unless a node sends before DDS has "
           "matched its peer" if not quiet and not cuts else
           f"{quiet} tick(s) went on before every process was quiet, so another run may differ" if quiet else
           f"{cuts} wait(s) ended by their wall-time limit before their simulated time (the machine was "
           "too busy), so another run may differ")
    return f"scenario {scenario_id} ran on lockstep simulated time ({ls.get('ticks', '?')} ticks; {how})"
