"""Which of a build's workspace packages a scenario runs: what its recording depends on.

Both the recording cache (``grader.grading.reuse``: a scenario's key digests these packages'
sources) and the time-scale choice (``grader.grading.timescale``: a package whose code paces by
the wall clock runs at 1x) need it; here, neither imports the other for it.
"""

from __future__ import annotations

import re
from pathlib import Path

from grader.scenario.model import Scenario

_DEPEND = re.compile(r"<(?:depend|exec_depend|build_depend|buildtool_depend)[^>]*>\s*([A-Za-z0-9_]+)\s*<")
_NAME = re.compile(r"<name>\s*([A-Za-z0-9_]+)\s*</name>")


def workspace_packages(src: Path) -> dict[str, tuple[Path, set[str]]]:
    """``{package: (folder, names it depends on)}`` of the staged sources of a build."""
    out: dict[str, tuple[Path, set[str]]] = {}
    for manifest in sorted(src.rglob("package.xml")):
        text = manifest.read_text(errors="replace")
        name = _NAME.search(text)
        if name:
            out[name.group(1)] = (manifest.parent, set(_DEPEND.findall(text)))
    return out


def packages_run(scenario: Scenario, packages: dict[str, tuple[Path, set[str]]]) -> set[str]:
    """Workspace packages a scenario runs: those its processes name (all of them for a launch
    file, which may start nodes of any package) and their workspace dependencies."""
    wanted: set[str] = set()
    for proc in scenario.processes:
        if proc.launch:                   # a launch file may start nodes of any package
            wanted |= set(packages)
        elif proc.package:
            wanted.add(proc.package)
    closure, todo = set(), list(wanted)
    while todo:
        name = todo.pop()
        if name in closure or name not in packages:
            continue
        closure.add(name)
        todo += packages[name][1]
    return closure
