"""Scenario child process: ``python -m grader.scenario.run RUN.json OUT_DIR``.

Runs one scenario (a :class:`grader.scenario.runspec.ScenarioRun`) in its own isolated ROS graph:
recorder first (so it sees everything; a thread of this process, see
``grader.bag.recorder_thread``), then the reference simulator, the driver, the student's
processes, the steps; then stops the student's processes, the simulator (which saves its canvas)
and the recorder (which finalizes the bag). Writes ``OUT_DIR/scenario.json``.
With ``time_scale`` > 1 the simulator (or ``grader_clock``) owns simulated time and every node
runs with ``use_sim_time`` (see :mod:`grader.scenario.simtime`); the clock is held while a
student process starts, and the run stops early with ``time_scale.fallback`` in the record when
the watchdog says it would not grade like 1x (:mod:`grader.scenario.watchdog`).
Runs in a child process started with a trusted environment (``rosenv.trusted_env``): the students'
interface types import here from the grader's own build of their definitions, never from theirs
(``grader.workspace.trusted_interfaces``), and rclpy state never leaks between scenarios.

Starting the students' processes (limits, scripted stdin, the wait until a node is up) is
:mod:`grader.scenario.launcher`.
"""

from __future__ import annotations

import faulthandler
import contextlib
import os
import signal
import socket
import sys
import time
import traceback
from pathlib import Path
from typing import Any, Iterator, cast

from grader.contracts.scenario_record import ScenarioRecord
from grader.contracts.output_folder import CANVAS_PNG, SCENARIO_JSON
from grader.bag.recorder_thread import RecorderThread
from grader.errors import GraderError
from grader.runner import ManagedProcess, ProcessSpec, RosGraph
from grader.scenario.cpuwait import cpu_wait
from grader.contracts.events import EVENTS_TOPIC, STDOUT_TOPIC, Event
from grader.scenario.launcher import FIRST_CLOCK_S, Launcher
from grader.scenario.lockstep import LockstepFailed
from grader.scenario.runspec import ScenarioRun
from grader.scenario.watchdog import RateWatchdog
from grader.sim.clock import CLOCK_NODE, CLOCK_TOPIC
from grader.rosenv import simulator_env, add_interface_paths
from grader.sim import truth_pose_topic, sim_argv
from grader.sim.stepchannel import make_pair

RECORDER_READY_S = 10.0
SIM_READY_S = 15.0
#: wall seconds the driver waits for the simulator to hold the turtles at the scenario's end
END_HOLD_WAIT_S = 2.0
#: the simulator's own record of its poses, beside the bag until the recorder takes it in
SIM_RECORD = "sim_poses.record"


class _FallBack(Exception):
    """The run on simulated time would not grade like 1x (the watchdog's reason)."""


#: what decides how a participant discovers others: this process's own nodes (the recorder thread,
#: the driver) take the graph's values, like its children (a no-op when the parent already
#: started this process with the graph's environment, as ``run_scenario`` does)
DISCOVERY_ENV = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS",
                 "FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def _discover_like(graph: RosGraph) -> None:
    for key in DISCOVERY_ENV:
        if key in graph.env:
            os.environ[key] = graph.env[key]
        else:
            os.environ.pop(key, None)


def run_scenario_here(run: ScenarioRun, out: Path) -> dict[str, Any]:
    """Execute ``run``; returns (and writes) the scenario record."""
    from grader.scenario.runtime import Runtime  # noqa: PLC0415 - scenario.run loads in every scenario child process; scenario.runtime only on this path
    from grader.scenario.steps import prepare  # noqa: PLC0415 - scenario.run loads in every scenario child process; scenario.steps only on this path

    spec = run.scenario
    scale = run.time_scale if run.time_scale > 1 and not run.lockstep else None
    sim_time = bool(scale) or run.lockstep     # on simulated time: the clock is the simulator's
    clock_node = (run.sim_node if spec.sim else CLOCK_NODE) if sim_time else None
    #: where the record says how the clock ran (and why it fell back)
    clock_key = "lockstep" if run.lockstep else "time_scale"
    out.mkdir(parents=True, exist_ok=True)
    record: dict[str, Any] = {"scenario": run.id, "steps": [], "processes": {}, "errors": [],
                              "bag": str(out / "bag"), "canvas": None}
    if scale:
        record["time_scale"] = {"used": scale}
    if run.lockstep:
        record["lockstep"] = {"used": True}
    t_start = time.monotonic()
    students: dict[str, ManagedProcess] = {}
    driver = recorder = sim = None
    #: lockstep with our simulator: the stepper's end of the step channel, the simulator's end
    steps = make_pair() if run.lockstep and spec.sim else None
    # the students' processes get their build's environment (as its setup.bash gives it), the
    # grader's processes the trusted one (rosenv.trusted_env)
    with RosGraph(out, prefixes=[Path(p) for p in run.prefixes],
                  interfaces=[Path(p) for p in run.interfaces]) as graph:
        record["domain_id"] = graph.domain_id
        _discover_like(graph)
        try:
            with _interrupt_after():
                recorder = _recorder(run, out, graph, scale, sim_time)
            # on simulated time the clock owner starts alongside the recorder: the clock is held
            # below until the recorder records it, so nothing is missed
            sim = _start_clock_owner(graph, run, out, record, scale) if scale else None
            try:
                recorder.start(RECORDER_READY_S)
            except GraderError as exc:
                record["errors"].append(str(exc))
            if not scale:
                sim = _start_clock_owner(graph, run, out, record, scale, steps[1] if steps else None)
            driver = _driver(run, graph, students, recorder, sim, scale, clock_node,
                             steps[0] if steps else None)
            start_hold = _bring_up(run, driver, recorder, sim, record, scale, clock_node)
            launcher = Launcher(run, graph, driver, students)
            rt = Runtime(driver, run, launcher.start, launcher.members)
            prepare(rt)
            _announce(run, driver, graph.domain_id)
            for proc in spec.processes:
                if proc.autostart:
                    launcher.start(proc.name)
            start_hold.close()
            _run_steps(rt, students, record)
            driver.clock.sleep(0.5)    # let the last messages reach the recorder
            _check_watchdog(driver)
            driver.graph_snapshot()
            driver.event(Event.SCENARIO_END, scenario=run.id)
        except (_FallBack, LockstepFailed) as exc:
            record[clock_key]["fallback"] = str(exc)
        except KeyboardInterrupt:
            # SIGTERM from the parent (batch Ctrl-C or time limit): stop, but keep what was recorded
            record["errors"].append("interrupted: the scenario was stopped before it finished")
            record["interrupted"] = True
            if driver is not None:
                driver.event(Event.SCENARIO_INTERRUPTED)
        except Exception as exc:  # noqa: BLE001 - recorded; the bag so far is still finalized
            record["errors"].append(f"{type(exc).__name__}: {exc}")
            record["traceback"] = traceback.format_exc()
            if driver is not None:
                driver.event(Event.SCENARIO_ERROR, error=f"{type(exc).__name__}: {exc}")
        finally:
            _wind_down(record, graph, out, driver, recorder, sim, students, scale)
    record["active_s"] = round(sum(s["duration_s"] for s in record["steps"]), 3)
    record["wall_s"] = round(time.monotonic() - t_start, 3)
    ScenarioRecord.from_working(record, str(out / SCENARIO_JSON)).write(out / SCENARIO_JSON)
    return record


def _recorder(run: ScenarioRun, out: Path, graph: RosGraph, scale: float | None, sim_time: bool) -> RecorderThread:
    """The scenario's recorder (not started): the rubric's topics, or all. The driver's events
    and output lines go into the bag in process (local topics): a student node publishing
    "/grader/events" adds nothing to the recording."""
    spec = run.scenario
    topics = None if spec.record == "all" else list(spec.record) + ["/grader/events", "/grader/stdout"]
    if topics is not None and sim_time:
        topics.append(CLOCK_TOPIC)      # maps the bag's wall-clock times to simulated time
    return RecorderThread(out / "bag", topics, domain_id=graph.domain_id,
                          extra=["--time-scale", repr(scale)] if scale else
                          ["--lockstep"] if run.lockstep else (),
                          local=(EVENTS_TOPIC, STDOUT_TOPIC))


def _driver(run: ScenarioRun, graph: RosGraph, students: dict[str, ManagedProcess], recorder: RecorderThread,
            sim: ManagedProcess | None, scale: float | None, clock_node: str | None,
            steps: socket.socket | None = None) -> Any:
    """The scenario's driver, told what the recorder has matched and recorded, and in lockstep
    which processes to wait for (the simulator's and the students', not the recorder's thread)
    and the step channel to the simulator (``steps``, :mod:`grader.sim.stepchannel`)."""
    from grader.scenario.driver import Driver  # noqa: PLC0415 - scenario.run loads in every scenario child process; scenario.driver only on this path

    driver = Driver(graph.domain_id, students, sim_node=run.sim_node, time_scale=scale or 1.0,
                    clock_node=clock_node, sink=recorder.post,
                    recording_matched=lambda t, n: not recorder.records(t) or recorder.matched(t, n),
                    recorded_count=lambda t: recorder.recorded(t) if recorder.records(t) else None,
                    lockstep=(lambda: [p.pid for p in [sim, *students.values()]
                                       if p is not None and p.alive()]) if run.lockstep else None,
                    lockstep_exclude=lambda: {t for t in (recorder.native_id,) if t is not None},
                    lockstep_channel=steps)
    graph.limits.on_limit = lambda **hit: driver.event(Event.LIMIT_HIT, **hit)
    return driver


def _bring_up(run: ScenarioRun, driver: Any, recorder: RecorderThread, sim: ManagedProcess | None,
              record: dict[str, Any], scale: float | None, clock_node: str | None) -> contextlib.ExitStack:
    """Wait until the clock runs, the simulator's poses are recorded and the recorder has the
    clock owner's topics; returns the hold on the clock to release once the autostarted
    processes are up (on simulated time)."""
    sim_time = bool(scale) or run.lockstep
    if run.lockstep and recorder.records(CLOCK_TOPIC):
        # every tick's /clock is recorded, the first included: a pose recorded before any
        # /clock maps to no tick (CI saw the first pose 13 ms of wall time off its tick)
        driver.wait_until(lambda: recorder.matched(CLOCK_TOPIC, 1), RECORDER_READY_S, wall=True)
    if sim_time:
        if not driver.clock.wait_for_clock(SIM_READY_S):
            raise RuntimeError(f"no {CLOCK_TOPIC} from the grader's clock within {SIM_READY_S:.0f}s")
    if scale:
        driver.watchdog = RateWatchdog(run.expected_rates, clock_owner=cast(str, clock_node))
        for expect in run.expected_rates:
            driver.count_messages(expect.topic, None, wait_s=0.0)
    if sim is not None:
        driver.watch_pose()
        driver.prepare_turtle_hold()     # placements' holds and the one at the end (below)
        if not driver.wait_until(lambda: driver.pose is not None, SIM_READY_S):
            raise RuntimeError("the reference simulator published no pose within "
                               f"{SIM_READY_S:.0f}s: " + sim.errors()[-500:])
        _wait_recorded(driver, recorder, record)
    start_hold = contextlib.ExitStack()
    if sim_time:
        # the clock is held from here until the autostarted processes are up: a recorder
        # still discovering the clock owner's topics would miss K times more of the start
        start_hold.enter_context(driver.clock.held())
        driver.wait_until(lambda: driver.recorder_matched((cast(str, clock_node), "/")), RECORDER_READY_S,
                          wall=True)
        time.sleep(FIRST_CLOCK_S)
    return start_hold


def _announce(run: ScenarioRun, driver: Any, domain_id: int) -> None:
    """The scenario's start in the bag: its id, the packages the build made (a contract's names
    are looked up in them) and each launch file as resolved."""
    driver.event(Event.SCENARIO_START, scenario=run.id, domain_id=domain_id, sim_node=run.sim_node)
    if run.packages:
        driver.event(Event.PACKAGES, packages={n: f.model_dump(mode="json") for n, f in run.packages.items()})
    for proc in run.scenario.processes:
        if proc.launch:
            driver.event(Event.LAUNCH_RESOLVED, process=proc.name,
                         launch=run.launch_files.get(proc.name, proc.launch),
                         installed=run.launch_installed.get(proc.name, False),
                         notes=list(run.notes.get(proc.name, ())),
                         nodes=[lp.model_dump(include={"name", "node_name", "package", "executable",
                                                       "stand_in", "error", "start_delay"})
                                for lp in run.launched.get(proc.name, ())])


def _run_steps(rt: Any, students: dict[str, ManagedProcess], record: dict[str, Any]) -> None:
    """Every step in order, its outcome in the record; a step is skipped once no student process
    is left (build failed, crashed on start-up: waiting for its limit would only cost time, the
    bag says why), and an ``on_timeout: abort`` step that timed out ends the scenario."""
    from grader.scenario.steps import action_name, run_step  # noqa: PLC0415 - scenario.run loads in every scenario child process; scenario.steps only on this path

    spec, driver = rt.scenario, rt.driver
    for step in spec.steps:
        if spec.processes and step.start is None and not any(p.alive() for p in students.values()):
            driver.event(Event.STEP_SKIPPED, step=step.id, reason="no student process is running",
                         exited={n: p.returncode for n, p in students.items()})
            record["steps"].append({"id": step.id, "action": action_name(step), "duration_s": 0.0,
                                    "ended_by": "skipped", "detail": {}})
            continue
        outcome = run_step(rt, step)
        record["steps"].append(outcome)
        _check_watchdog(driver)
        if outcome["ended_by"] == "timeout" and step.on_timeout == "abort":
            driver.event(Event.SCENARIO_ABORTED, step=step.id)
            break


def _wind_down(record: dict[str, Any], graph: RosGraph, out: Path, driver: Any, recorder: RecorderThread | None,
               sim: ManagedProcess | None, students: dict[str, ManagedProcess], scale: float | None) -> None:
    """However the scenario ended: how starved it was, the turtles held, the clock stopped, every
    process stopped (and how it ended), the simulator's record written into the bag."""
    record["output_cut"] = graph.output_cuts()
    # how starved the run was (before anything is stopped): see grader.scenario.cpuwait
    record["cpu_wait"] = cpu_wait({"scenario": os.getpid(), "turtlesim": sim.pid if sim is not None else None,
                                   **{n: p.pid for n, p in students.items() if p.alive()}})
    # the scenario is over: the turtles are held still before the student's processes
    # stop, or a turtle coasts on its last command (turtlesim's 1 s command timeout)
    # after the scenario, drawing on the canvas the grade reads (bench_flake: a canvas
    # item 2.5/5/2.5 over three runs of the same code, by how far the coast went)
    if sim is not None and driver is not None and sim.alive() and not record.get("interrupted"):
        driver.hold_turtles(True, "scenario_end", wait_s=END_HOLD_WAIT_S)
    # on simulated time the shutdown's wall time must not run the simulation on
    if scale and driver is not None and not driver.clock.stop():
        record["time_scale"].setdefault("fallback", "a node other than the grader's driver held "
                                                    "or stopped the simulated clock")
    for name, student in students.items():
        crashed = student.returncode is not None and not student.stopped_by_grader
        rc = student.stop()
        record["processes"][name] = {"returncode": rc, "crashed": crashed and rc != 0,
                                     "exited_early": crashed, "timed_out": student.timed_out,
                                     "killed": student.killed}
    if driver is not None:
        if scale:
            record["time_scale"].update(sim_s=round(driver.clock.sim_s(), 3),
                                        held_s=round(driver.clock.held_s, 3))
        if driver.clock.stepper is not None:
            record["lockstep"].update(driver.clock.stepper.summary())
        driver.shutdown()
    graph.stop_all()
    if recorder is not None:
        # the simulator has stopped and closed its record: the recorder writes it into
        # the bag (grader.sim.record: the only poses a grade rests on)
        recorder.stop(records=[out / SIM_RECORD] if (out / SIM_RECORD).exists() else [])
        (out / SIM_RECORD).unlink(missing_ok=True)


def _wait_recorded(driver: Any, recorder: RecorderThread | None, record: dict[str, Any]) -> None:
    """Go on only once the recorder has recorded the simulator's poses (both topics).

    The driver hearing the simulator says nothing about the recorder: it is another DDS
    participant, and discovery between two participants takes up to ~1 s on a loaded machine
    (grader/dds/fastdds_profile.xml). A scenario whose student code cannot start ends ~0.5 s
    after this point; ``make demo`` recorded such a scenario (goal_setter's handout, graded
    while other submissions were built) with no pose at all, and its pose integrity check
    became "could not check" instead of "pass" (a test reproduces it with a recorder that
    discovers the simulator late)."""
    if recorder is None:
        return
    pose = driver.pose_topic or "/turtle1/pose"
    # only the topics this scenario records (a rubric's `record:` list may leave the copy out)
    wanted = [t for t in (pose, truth_pose_topic(pose)) if recorder.records(t)]
    if not wanted:
        return
    # (in lockstep the simulator publishes only on a tick: this wait ticks, before any student starts)
    if not driver.wait_until(lambda: all(recorder.recorded(t) for t in wanted), RECORDER_READY_S, wall=True,
                             react=True):
        missing = [t for t in wanted if not recorder.recorded(t)]
        record["errors"].append(f"the recorder recorded nothing on {', '.join(missing)} within "
                                f"{RECORDER_READY_S:.0f} s of the simulator's first pose")


def _start_clock_owner(graph: RosGraph, run: ScenarioRun, out: Path, record: dict[str, Any],
                       scale: float | None, steps: socket.socket | None = None) -> ManagedProcess | None:
    """The reference simulator (with the clock on simulated time), or without one on simulated
    time ``grader_clock``; returns the simulator's process (None without a simulator).
    ``steps``: the simulator's end of lockstep's step channel, which it alone inherits (closed
    here once it has it)."""
    if run.scenario.sim:
        canvas = out / CANVAS_PNG
        record["canvas"] = str(canvas)
        fds = () if steps is None else (steps.fileno(),)
        try:
            return graph.start(ProcessSpec("turtlesim", sim_argv(
                canvas_out=canvas, ros_args=["-r", f"__node:={run.sim_node}"], time_scale=scale,
                pose_record=out / SIM_RECORD, lockstep=run.lockstep, step_fd=fds[0] if fds else None),
                env=simulator_env(graph.env), pass_fds=fds))
        finally:
            if steps is not None:
                steps.close()
    if scale:
        graph.start(ProcessSpec(CLOCK_NODE, sim_argv(time_scale=scale, clock_only=True)))
    return None


def _check_watchdog(driver) -> None:
    if driver.watchdog is not None:
        running = {name: p.pid for name, p in driver.processes.items() if p.alive()}
        reason = driver.watchdog.verdict(driver.node, driver.clock.sim_s(), driver.student_publishes) \
            or driver.watchdog.busy(running)
        if reason:
            raise _FallBack(reason)


_DEFERRED = {"depth": 0, "pending": False}


def _interrupt_once(*_args) -> None:
    """First SIGTERM unwinds the scenario like Ctrl-C; later ones must not break the clean-up."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if _DEFERRED["depth"]:
        _DEFERRED["pending"] = True
        return
    raise KeyboardInterrupt


@contextlib.contextmanager
def _interrupt_after() -> Iterator[None]:
    """A SIGTERM inside the block unwinds at its end: the recorder's bag file is created and its
    owner known before the scenario can be stopped (else nobody would finalize that file)."""
    _DEFERRED["depth"] += 1
    try:
        yield
    finally:
        _DEFERRED["depth"] -= 1
        if not _DEFERRED["depth"] and _DEFERRED["pending"]:
            _DEFERRED["pending"] = False
            raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m grader.scenario.run RUN.json OUT_DIR", file=sys.stderr)
        return 2
    run = ScenarioRun.model_validate_json(Path(argv[0]).read_text())

    add_interface_paths()     # a grader process: the students' types from the grader's own build of them
    faulthandler.enable()      # a crash in rclpy leaves the Python stacks in scenario.log
    # SIGTERM from the parent (batch Ctrl-C, time limit) → unwind through the finally blocks
    signal.signal(signal.SIGTERM, _interrupt_once)
    record = run_scenario_here(run, Path(argv[1]))
    return 0 if not record["errors"] else 1


if __name__ == "__main__":
    sys.exit(main())
