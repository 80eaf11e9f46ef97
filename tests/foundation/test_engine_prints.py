"""The engine prints nothing for the user (issue 38): a command's words are its front-end's.

The engine returns what a command shows (``grading.outputs.check_table``, ``api.BatchResult``)
or hands it to a callback (``on_notice``, ``progress``), and the front-ends (``grader.commands``,
``grader.lms``, the doctor, ...) print. The engine's only ``print`` calls are those of processes
the grader starts, whose output is their protocol or their log, each listed below with what it
is. The scan is of the source (``ast``), so a print on a path no test takes is seen too.
"""

from __future__ import annotations

import ast
from pathlib import Path

GRADER = Path(__file__).resolve().parents[2] / "grader"
FRONT_ENDS = ("cli", "commands", "testing", "doctor", "bootstrap", "selftest", "audit", "lms", "api")
#: engine modules that are a process's own entry point: what they print is that process's output
PROCESSES = {
    "grader.bag.recorder": "the recorder process: its READY/RECORDED lines and log (`grader record`)",
    "grader.bag.replay": "the replay process: READY/DONE to its parent, its start line (`grader replay`)",
    "grader.bag.loadgen": "the load generator the recorder's benchmarks start: READY/DONE to its parent",
    "grader.sim.process": "the simulator process's log (late ticks, a canvas it could not save)",
    "grader.sim.cli": "`python -m grader.sim`: its error line",
    "grader.scenario.run": "the scenario child's usage line",
    "grader.launch.describe": "a launch file described in a subprocess: JSON to its parent",
    "grader.sandbox.enter": "a scenario's PID 1: its usage and option errors",
    "grader.cache.code": "`python -m grader.cache.code`: the digests, for whoever changes the grader",
}


def _module(path: Path) -> str:
    parts = path.relative_to(GRADER.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _prints(path: Path) -> list[int]:
    return [node.lineno for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print"]


def _engine() -> dict[str, Path]:
    modules = {_module(p): p for p in GRADER.rglob("*.py")}
    return {m: p for m, p in modules.items() if (m.split(".") + [""])[1] not in FRONT_ENDS}


def test_the_engine_prints_only_in_the_processes_it_starts() -> None:
    found = {m: lines for m, p in sorted(_engine().items()) if (lines := _prints(p))}
    unlisted = {m: lines for m, lines in found.items() if m not in PROCESSES}
    assert not unlisted, f"engine modules that print (return the text, or take a callback): {unlisted}"
    assert set(PROCESSES) <= set(found), f"listed but print nothing: {set(PROCESSES) - set(found)}"
