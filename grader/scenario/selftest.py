"""`grader doctor`'s two self-tests, run by the engine and printed by the doctor (through
``grader.api.machine``): two ROS processes that must hear each other in an isolated graph
(:func:`live_selftest`), and a real scenario (reference simulator, recorder, driver) with one
sandboxed student-like rclpy node that must hear the simulator's poses over the scenario's
loopback, and must not see or change anything it should not (:func:`sandbox_selftest`).

It lived in ``grader.sandbox`` (floor 2) and ran a scenario (floor 4) from there; here it is on
the scenario's floor, so no import runs up a floor."""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

from grader.contracts.process import Limits
from grader.runner import ProcessSpec, RosGraph, python_argv
from grader.sandbox.probe import protections
from grader.scenario import run_scenario
from grader.scenario.model import Scenario
from grader.scenario.runspec import LaunchedProcess, ScenarioRun

LISTENER = r"""
import json, os, sys, time
# an empty directory shows nothing (an installed grader package is covered by an empty tmpfs)
report = {"uid": os.getuid(), "wrote": [],
          "sees": [p for p in sys.argv[1:] if os.path.exists(p) and (not os.path.isdir(p) or os.listdir(p))]}
for p in sys.argv[1:]:
    try:
        probe = os.path.join(p, "sandbox-selftest")
        with open(probe, "w") as f:
            f.write("x")
        report["wrote"].append(p)
        os.remove(probe)   # proof taken: leave nothing behind where the sandbox let it write
    except OSError:
        pass
import rclpy
from turtlesim.msg import Pose
rclpy.init()
node = rclpy.create_node("sandbox_selftest")
got = []
t0 = time.monotonic()
node.create_subscription(Pose, "/turtle1/pose", lambda m: got.append(time.monotonic()), 10)
while len(got) < 10 and time.monotonic() - t0 < 20:
    rclpy.spin_once(node, timeout_sec=0.1)
report["poses"] = len(got)
report["first_pose_s"] = round(got[0] - t0, 3) if got else None
print("SELFTEST " + json.dumps(report), flush=True)
sys.exit(0 if len(got) >= 10 else 1)
"""


def live_selftest(timeout: float) -> tuple[bool, str]:
    """Start a talker and a listener as separate processes in an isolated graph."""
    with tempfile.TemporaryDirectory(prefix="grader-doctor-") as tmp, RosGraph(Path(tmp)) as graph:
        t0 = time.monotonic()
        graph.start(ProcessSpec("talker", python_argv("grader.selftest", "talk")))
        listener = graph.start(ProcessSpec("listener", python_argv("grader.selftest", "listen", str(timeout)),
                                           limits=Limits(wall_s=timeout + 5)))
        rc = listener.wait(timeout + 10)
        detail = (listener.output().strip() or listener.errors().strip().splitlines()[-1:] or ["no output"])
        detail = detail if isinstance(detail, str) else detail[0]
        return rc == 0, f"{detail} in {time.monotonic() - t0:.1f}s on ROS_DOMAIN_ID {graph.domain_id}"


def sandbox_selftest(timeout_s: float = 30.0) -> tuple[bool, str]:
    fs_on = next(p.active for p in protections() if p.name == "filesystem")
    package = Path(__file__).resolve().parents[1]
    hidden = [str(p) for p in (package, package.parent / "rubrics") if p.exists()]
    scenario = Scenario.model_validate({
        "processes": [{"name": "listener", "package": "selftest", "module": "selftest:main"}],
        "steps": [{"id": "listen", "until": {"condition": "process_exit", "process": "listener"},
                   "timeout": timeout_s}]})
    with tempfile.TemporaryDirectory(prefix="grader-doctor-sandbox-") as tmp:
        argv = (sys.executable, "-c", LISTENER, *hidden, tmp)
        run = ScenarioRun(id="sandbox-selftest", scenario=scenario, launched={"listener": (
            LaunchedProcess(name="listener", process="listener", argv=argv),)})
        t0 = time.monotonic()
        record = run_scenario(run, Path(tmp) / "out")
        wall = time.monotonic() - t0
        log = (Path(tmp) / "out" / "logs" / "listener.stdout.log")
        lines = [ln for ln in (log.read_text(errors="replace") if log.exists() else "").splitlines()
                 if ln.startswith("SELFTEST ")]
        if not lines:
            err = Path(tmp) / "out" / "logs" / "listener.stderr.log"
            tail = (err.read_text(errors="replace").strip().splitlines() if err.exists() else [])[-1:]
            return False, f"the sandboxed node reported nothing ({'; '.join(record.errors + tail)})"
        report = json.loads(lines[-1][len("SELFTEST "):])
    problems = []
    if report["poses"] < 10:
        problems.append(f"heard {report['poses']} poses from the simulator")
    if fs_on and report["sees"]:
        problems.append("could see " + ", ".join(report["sees"]))
    if fs_on and report["wrote"]:
        problems.append("could write into " + ", ".join(report["wrote"]))
    if problems:
        return False, "; ".join(problems)
    seen = ("grader sources, rubrics and outputs invisible" if fs_on
            else "NOT isolated: it could see " + ", ".join(report["sees"]))
    return True, f"first simulator pose after {report['first_pose_s']} s; uid {report['uid']}; {seen} ({wall:.1f} s)"
