"""Starting a rubric's processes in a scenario child: each OS process (one, or a launch file's
nodes), its limits, its scripted stdin, and the wait until its node is up.

Split from :mod:`grader.scenario.run`, which runs the scenario's one sequence; a process starts
while the scenario clock is held (:meth:`grader.scenario.simtime.ScenarioClock.held`), so a
step's limit never pays for a start-up. Scripted stdin is typed from a thread of the process,
after its node is up and its topics recorded (a person types after the prompt), or in lockstep
by the thread that ticks, each line at the same simulated time in every run.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from typing import Any, Sequence

from grader.runner import UNTRUSTED, UNTRUSTED_NPROC, ManagedProcess, ProcessSpec, RosGraph
from grader.contracts.events import Event
from grader.contracts.process import Limits
from grader.scenario.model import Process
from grader.scenario.runspec import LaunchedProcess, ScenarioRun

#: a ROS node exits within a second of Ctrl-C; one blocked in input() ignores it (rclpy handles
#: SIGINT itself) and would otherwise cost the full default grace at the end of every scenario
STUDENT_STOP_GRACE_S = 2.0
#: wall seconds a starting process may hold the clock until its node is up (at 1x: scenario time
#: stands still meanwhile, so a step's limit never pays for a start-up; see ScenarioClock.held)
NODE_UP_S = 15.0
#: then wall seconds until the clock owner has matched the new nodes' /clock readers
CLOCK_MATCH_S = 5.0
#: and for the new nodes to take the held /clock (and the recorder to match their publishers:
#: DDS matching lags the graph) before the clock runs again
FIRST_CLOCK_S = 0.3


class _EventedProcess(ManagedProcess):
    """A student process whose scripted stdin lines are announced on /grader/events."""

    driver = None

    def pause_before_line(self, seconds: float) -> bool:
        """A line's delay in scenario time (simulated when the run is faster than real time)."""
        if self.driver is None or not self.driver.clock.simulated:
            return super().pause_before_line(seconds)
        return self.driver.clock.sleep(seconds, stop=lambda: self.popen.poll() is not None)

    def on_stdin_line(self, text: str) -> None:
        if self.driver is not None:
            self.driver.event(Event.STDIN_LINE, process=self.name, line=text, delivered=True)


class _SteppedProcess(_EventedProcess):
    """Lockstep: a student process whose scripted stdin lines are typed by the thread that ticks,
    each at the first tick boundary at or after its time (:meth:`Stepper.schedule`), so it reaches
    the node at the same simulated time in every run; :meth:`type_from` schedules the script."""

    def _feed_stdin(self) -> None:
        """Nothing to feed from a thread of its own (see the class)."""

    def type_from(self, stepper: Any, start_ns: int) -> None:
        t = start_ns
        for line in self.spec.stdin or ():
            t += round(line.delay * 1e9)
            stepper.schedule(t, lambda text=line.line: self._type(text))
        if self.spec.close_stdin:
            stepper.schedule(t, self._close_stdin)

    def _type(self, text: str) -> None:
        pipe = self.popen.stdin
        if pipe is None or pipe.closed or self.popen.poll() is not None:
            return
        try:
            os.set_blocking(pipe.fileno(), False)   # a node that never reads must not stop the clock
            os.write(pipe.fileno(), (text + "\n").encode())
        except (OSError, ValueError):             # exited, closed its stdin, or its pipe is full
            return
        self.on_stdin_line(text)

    def _close_stdin(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            if self.popen.stdin is not None:
                self.popen.stdin.close()


#: scenario seconds between a process's node being up (its topics recorded) and its first
#: scripted line's delay starting: a person types after the prompt
STDIN_AFTER_UP_S = 0.3


def _nodes(names: set) -> list[str]:
    return sorted("/".join(n[::-1]).replace("//", "/") for n in names)


def _open_gate(driver, proc: ManagedProcess, before: set, gate: threading.Event) -> None:
    """Let the stdin script start once the process's node is up and its topics are recorded."""
    deadline = time.monotonic() + 15.0
    new: set = set()
    while time.monotonic() < deadline and proc.alive():
        new = driver.student_nodes() - before
        if new and all(driver.recorder_matched(n) for n in new):
            driver.clock.sleep(STDIN_AFTER_UP_S)
            break
        time.sleep(0.05)
    driver.event(Event.STDIN_READY, process=proc.name, nodes=_nodes(new))
    gate.set()


def process_limits(proc: Process, scenario_wall_s: float) -> Limits:
    """The rubric's limits for a student process over the grader's defaults for student code."""
    return Limits(wall_s=proc.limits.wall_s or scenario_wall_s,
                  cpu_s=proc.limits.cpu_s or UNTRUSTED.cpu_s,
                  memory_mb=proc.limits.memory_mb or UNTRUSTED.memory_mb)


class Launcher:
    """Starts a rubric process: each of its OS processes (one, or a launch file's nodes)."""

    def __init__(self, run: ScenarioRun, graph: RosGraph, driver, students: dict[str, ManagedProcess]) -> None:
        self.run, self.graph, self.driver, self.students = run, graph, driver, students
        self.members: dict[str, list[str]] = {p.name: [] for p in run.scenario.processes}

    def start(self, name: str) -> list[str]:
        proc = self.run.scenario.process(name)
        clock = self.driver.clock
        if proc.start_delay:
            clock.sleep(proc.start_delay)
        launched: Sequence[LaunchedProcess] = self.run.launched.get(name, ())
        started: list[str] = []
        launched = [lp for lp in launched if not lp.stand_in]   # the reference sim plays those
        delayed = [lp for lp in launched if lp.start_delay > 0]
        with clock.held():
            before = self.driver.student_nodes(), clock.clock_readers()
            for lp in launched:
                if lp.start_delay <= 0 and self._start_one(proc, lp):
                    started.append(lp.name)
            self._wait_up(before, started)
            self._type_scripts(started, before[0])
        for lp in delayed:      # a launch file's TimerAction: start later, without blocking steps
            if clock.simulated:
                threading.Thread(target=self._start_later, args=(proc, lp), daemon=True).start()
            else:
                threading.Timer(lp.start_delay, self._start_one, args=(proc, lp)).start()
            started.append(lp.name)
        return started

    def _start_later(self, proc: Process, lp: LaunchedProcess) -> None:
        clock = self.driver.clock
        clock.sleep(lp.start_delay)
        with clock.held():
            before = self.driver.student_nodes(), clock.clock_readers()
            if self._start_one(proc, lp):
                self._wait_up(before, [lp.name])
                self._type_scripts([lp.name], before[0])

    def _type_scripts(self, names: list[str], before: set) -> None:
        """Lockstep, while the clock is held (its time the same in every run): schedule the
        scripted stdin of the processes just started, from ``STDIN_AFTER_UP_S`` after now (their
        nodes were waited for, :meth:`_wait_up`)."""
        stepper = self.driver.clock.stepper
        for name in names:
            managed = self.students.get(name)
            if stepper is None or not isinstance(managed, _SteppedProcess):
                continue
            managed.type_from(stepper, stepper.now_ns + round(STDIN_AFTER_UP_S * 1e9))
            self.driver.event(Event.STDIN_READY, process=name, nodes=_nodes(self.driver.student_nodes() - before))

    def _wait_up(self, snapshot: tuple[set, int | None], names: list[str]) -> None:
        """While the clock is held: wait (wall time) until the started processes' nodes are in
        the graph with their topics recorded, their ``/rosout`` included (or the processes
        ended). A line a node logs in its constructor reaches the bag only so: ``/rosout`` keeps
        it for a subscriber that matches later (transient local, 10 s lifespan), but not once
        the node has stopped; bench_flake at load ~24 recorded a correct greeter's one line in
        two runs of three, and the third told the student it had not logged through ROS. On
        simulated time also until the clock owner has matched their ``/clock`` readers, then a
        moment for their first ``/clock``. ``snapshot``: the student nodes and matched readers before they started."""
        clock = self.driver.clock
        if not names:
            return
        driver = self.driver
        before, readers = snapshot

        def alive() -> list[str]:
            return [n for n in names if n in self.students and self.students[n].alive()]

        def up() -> bool:
            new = driver.student_nodes() - before
            return not alive() or (len(new) >= len(alive()) and all(driver.recorder_matched(n) for n in new)
                                   and driver.topic_recorded("/rosout"))

        def clocked() -> bool:
            now = clock.clock_readers()
            return not alive() or readers is None or now is None or \
                now >= readers + len(driver.student_nodes() - before)

        if driver.wait_until(up, NODE_UP_S, poll=0.02, wall=True) and clock.simulated and \
                driver.wait_until(clocked, CLOCK_MATCH_S, poll=0.02, wall=True):
            time.sleep(FIRST_CLOCK_S)

    def _start_one(self, proc: Process, lp: LaunchedProcess) -> bool:
        driver = self.driver
        if not lp.argv:
            driver.event(Event.NODE_UNAVAILABLE, process=lp.name, of=proc.name, package=proc.package,
                         executable=proc.executable, module=proc.module, launch=proc.launch, error=lp.error,
                         node_name=lp.node_name)
            return False
        script = list(proc.stdin or ()) if proc.launch is None else []
        stepped = bool(script) and self.driver.clock.stepper is not None
        gate = threading.Event() if script and not stepped else None
        before = driver.student_nodes()
        argv = list(lp.argv)
        if self.run.time_scale > 1 or self.run.lockstep:     # every node of the process follows /clock
            argv += ["--ros-args", "-p", "use_sim_time:=true"]
        managed = self.graph.start(ProcessSpec(
            lp.name, argv, env={**proc.env, **lp.env} or None,
            stdin=script if (script or proc.stdin is not None) else None,
            close_stdin=proc.stdin_close, limits=process_limits(proc, self.run.wall_limit_s),
            nproc=UNTRUSTED_NPROC, stop_grace_s=STUDENT_STOP_GRACE_S, term_grace_s=1.0, untrusted=True),
            process_class=_SteppedProcess if stepped else _EventedProcess, stdin_gate=gate)
        managed.driver = driver  # type: ignore[attr-defined]  # (an _EventedProcess)
        if gate is not None:
            threading.Thread(target=_open_gate, args=(driver, managed, before, gate), daemon=True).start()
        self.students[lp.name] = managed
        self.members[proc.name].append(lp.name)
        driver.event(Event.NODE_STARTED, process=lp.name, of=proc.name, package=proc.package,
                     executable=proc.executable, module=proc.module, launch=proc.launch,
                     node_name=lp.node_name, argv=list(lp.argv))
        return True
