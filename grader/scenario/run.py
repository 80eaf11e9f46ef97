"""Scenario child process: ``python -m grader.scenario.run SPEC.json OUT_DIR``.

Runs one scenario in its own isolated ROS graph: recorder first (so it sees everything), then the
reference simulator, the driver, the student's nodes, the steps; then stops the student's nodes,
the recorder (SIGINT finalizes the bag) and the simulator (which saves its canvas). Writes
``OUT_DIR/scenario.json``. Runs in a child process started with the build's environment, so the
student's interface types import here and rclpy state never leaks between scenarios.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any

from grader.bag.recorder import recorder_argv, wait_ready
from grader.errors import GraderError
from grader.runner import Limits, ManagedProcess, ProcessSpec, RosGraph, StdinLine
from grader.scenario.spec import Scenario

RECORDER_READY_S = 10.0
SIM_READY_S = 15.0
#: a ROS node exits within a second of Ctrl-C; one blocked in input() ignores it (rclpy handles
#: SIGINT itself) and would otherwise cost the full default grace at the end of every scenario
STUDENT_STOP_GRACE_S = 2.0


class _EventedProcess(ManagedProcess):
    """A student process whose scripted stdin lines are announced on /grader/events."""

    driver = None

    def on_stdin_line(self, text: str) -> None:
        if self.driver is not None:
            self.driver.event("stdin_line", process=self.name, line=text, delivered=True)


def _open_gate(driver, proc: ManagedProcess, before: set, gate: threading.Event) -> None:
    """Let the stdin script start once the process's node is up and its topics are recorded."""
    deadline = time.monotonic() + 15.0
    new: set = set()
    while time.monotonic() < deadline and proc.alive():
        new = driver.student_nodes() - before
        if new and all(driver.recorder_matched(n) for n in new):
            time.sleep(0.3)
            break
        time.sleep(0.05)
    driver.event("stdin_ready", process=proc.name, nodes=sorted("/".join(n[::-1]).replace("//", "/") for n in new))
    gate.set()


def run_scenario_here(spec: Scenario, out: Path) -> dict[str, Any]:
    """Execute ``spec``; returns (and writes) the scenario record."""
    from grader.scenario.driver import Driver
    from grader.scenario.steps import prepare, run_step

    out.mkdir(parents=True, exist_ok=True)
    record: dict[str, Any] = {"scenario": spec.id, "steps": [], "processes": {}, "errors": [],
                              "bag": str(out / "bag"), "canvas": None}
    t_start = time.monotonic()
    students: dict[str, ManagedProcess] = {}
    driver = None
    with RosGraph(out) as graph:
        record["domain_id"] = graph.domain_id
        try:
            recorder = graph.start(ProcessSpec("recorder", recorder_argv(out / "bag", spec.record or None),
                                               stop_grace_s=10.0))
            try:
                wait_ready(recorder.stdout_path, RECORDER_READY_S, proc=recorder)
            except GraderError as exc:
                record["errors"].append(f"{exc} {recorder.errors()[-500:]}")
            sim = None
            if spec.sim:
                from grader.sim import sim_argv
                canvas = out / "canvas.png"
                sim = graph.start(ProcessSpec("turtlesim", sim_argv(canvas_out=canvas, extra=spec.sim_args)))
                record["canvas"] = str(canvas)
            driver = Driver(graph.domain_id, students)
            if sim is not None:
                driver.watch_pose()
                if not driver.wait_until(lambda: driver.pose is not None, SIM_READY_S):
                    raise RuntimeError("the reference simulator published no pose within "
                                       f"{SIM_READY_S:.0f}s: " + sim.errors()[-500:])
            prepare(driver, spec.steps)
            # give the recorder a moment to discover the driver's topics before anything is sent
            driver.wait_until(lambda: driver.node.count_subscribers("/grader/events") >= 1, 5.0)
            driver.event("scenario_start", scenario=spec.id, domain_id=graph.domain_id)
            by_name = {n.name: n for n in spec.nodes}

            def start_node(name: str) -> bool:
                node = by_name[name]
                if node.start_delay_s:
                    time.sleep(node.start_delay_s)
                if not node.argv:
                    driver.event("node_unavailable", process=node.name, package=node.package,
                                 executable=node.executable, module=node.module, error=node.error)
                    return False
                script = [StdinLine(str(t), float(d)) for t, d in node.stdin_script]
                limits = Limits.untrusted(wall_s=node.wall_s or spec.time_limit_s)
                if node.cpu_s or node.memory_mb:
                    limits = Limits(wall_s=limits.wall_s, cpu_s=node.cpu_s or limits.cpu_s,
                                    address_space_mb=node.memory_mb or limits.address_space_mb,
                                    nproc=limits.nproc, nofile=limits.nofile)
                gate = threading.Event() if script else None
                before = driver.student_nodes()
                proc = graph.start(ProcessSpec(
                    node.name, node.argv + node.ros_args(), env=node.env or None,
                    stdin=script if (script or node.stdin) else None, close_stdin=node.stdin_close,
                    limits=limits, stop_grace_s=STUDENT_STOP_GRACE_S, term_grace_s=1.0),
                    process_class=_EventedProcess, stdin_gate=gate)
                proc.driver = driver
                if gate is not None:
                    threading.Thread(target=_open_gate, args=(driver, proc, before, gate),
                                     daemon=True).start()
                students[node.name] = proc
                driver.event("node_started", process=node.name, package=node.package,
                             executable=node.executable, module=node.module, argv=node.argv[3:])
                if node.ready:
                    ok = driver.wait_until(lambda: driver.is_ready(node.ready) or not proc.alive(),
                                           node.ready_timeout_s, poll=0.05) and proc.alive()
                    driver.event("node_ready" if ok else "node_not_ready", process=node.name,
                                 condition=node.ready)
                return True

            for node in spec.nodes:
                if node.autostart:
                    start_node(node.name)
            ctx: dict[str, Any] = {
                "start_node": start_node,
                "students_gone": lambda: bool(students) and not any(p.alive() for p in students.values())}
            for step in spec.steps:
                if spec.nodes and step.action() != "start" and students is not None \
                        and not any(p.alive() for p in students.values()):
                    # nobody left to grade (build failed, crashed on start-up): waiting for this
                    # step's timeout would only cost time; the bag says why
                    driver.event("step_skipped", step=step.id, reason="no student process is running",
                                 exited={n: p.returncode for n, p in students.items()})
                    record["steps"].append({"id": step.id, "action": step.action(), "duration_s": 0.0,
                                            "ended_by": "skipped", "detail": {}})
                    continue
                outcome = run_step(driver, step, ctx)
                record["steps"].append(outcome)
                if outcome["ended_by"] == "timeout" and step.abort_on_timeout:
                    driver.event("scenario_aborted", step=step.id)
                    break
            time.sleep(spec.settle_s)
            driver.graph_snapshot()
            driver.event("scenario_end", scenario=spec.id)
        except KeyboardInterrupt:
            # SIGTERM from the parent (batch Ctrl-C or time limit): stop, but keep what was recorded
            record["errors"].append("interrupted: the scenario was stopped before it finished")
            record["interrupted"] = True
            if driver is not None:
                driver.event("scenario_interrupted")
        except Exception as exc:  # noqa: BLE001 - recorded; the bag so far is still finalized
            record["errors"].append(f"{type(exc).__name__}: {exc}")
            record["traceback"] = traceback.format_exc()
            if driver is not None:
                driver.event("scenario_error", error=f"{type(exc).__name__}: {exc}")
        finally:
            for name, proc in students.items():
                crashed = proc.returncode is not None and not proc.stopped_by_grader
                rc = proc.stop()
                record["processes"][name] = {"returncode": rc, "crashed": crashed and rc != 0,
                                             "exited_early": crashed, "timed_out": proc.timed_out,
                                             "killed": proc.killed}
            if driver is not None:
                driver.shutdown()
            graph.stop_all()
    active = sum(s["duration_s"] for s in record["steps"])
    record["active_s"] = round(active, 3)
    record["wall_s"] = round(time.monotonic() - t_start, 3)
    (out / "scenario.json").write_text(json.dumps(record, indent=1, default=str))
    return record


def _interrupt_once(*_args) -> None:
    """First SIGTERM unwinds the scenario like Ctrl-C; later ones must not break the clean-up."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m grader.scenario.run SPEC.json OUT_DIR", file=sys.stderr)
        return 2
    spec = Scenario.from_dict(json.loads(Path(argv[0]).read_text()))
    # SIGTERM from the parent (batch Ctrl-C, time limit) → unwind through the finally blocks
    signal.signal(signal.SIGTERM, _interrupt_once)
    record = run_scenario_here(spec, Path(argv[1]))
    return 0 if not record["errors"] else 1


if __name__ == "__main__":
    sys.exit(main())
