"""Reusing a scenario's recording when nothing it runs has changed.

A scenario's bag depends only on what runs in it: the rubric's scenario (its model, as JSON), the
source of every package it starts and of the workspace packages those depend on, the files it
replays, and the grader itself. When all of these are byte-identical to a run already recorded
(a template package untouched by half the class, a student re-running ``grader check`` after
fixing one node), the recording is copied instead of run again. The result says which scenarios
were reused and from where (never silent); ``--no-reuse`` turns it off.

Recordings live beside the build cache (``<cache>/recordings/<key>/``); a per-key lock makes a
second submission with the same key wait for the first one's recording instead of running it
twice.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import re
import shutil
import time
from pathlib import Path
from typing import Any, Iterator

from grader import __version__
from grader.scenario.model import Scenario

#: files of a scenario folder that make up its recording
RECORDING = ("bag", "logs", "canvas.png", "scenario.json", "run.json", "scenario.log")
#: bump when the scenario runtime changes what it records for the same inputs (2: executables
#: found and started as `ros2 run` does; 3: the driver's client ids in its service_call events,
#: the simulator's record of its poses, events in process)
RECORDING_FORMAT = 3
_DEPEND = re.compile(r"<(?:depend|exec_depend|build_depend|buildtool_depend)[^>]*>\s*([A-Za-z0-9_]+)\s*<")
_NAME = re.compile(r"<name>\s*([A-Za-z0-9_]+)\s*</name>")


def _tree_digest(path: Path) -> str:
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for f in files:
        h.update(str(f.relative_to(path) if path.is_dir() else f.name).encode() + b"\0")
        h.update(f.read_bytes())
    return h.hexdigest()


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


def scenario_key(scenario_id: str, scenario: Scenario, build: Any, settings: str = "") -> str | None:
    """The recording's identity, or None when it cannot be reused (no build). ``settings``: how
    the recording was made beyond the scenario (e.g. its time scale)."""
    if build is None:
        return None
    packages = workspace_packages(Path(build.root) / "src")
    closure = packages_run(scenario, packages)
    h = hashlib.sha256(f"{__version__}:{RECORDING_FORMAT}:{settings}:{scenario_id}".encode())
    h.update(scenario.model_dump_json().encode())
    for name in sorted(closure):
        h.update(f"{name}:{_tree_digest(packages[name][0])}".encode())
        status = build.packages[name].status if name in build.packages else "absent"
        h.update(status.encode())
    for step in scenario.steps:
        if step.replay is not None:
            h.update(_tree_digest(step.replay.bag).encode())
    if any(proc.package and proc.package not in packages for proc in scenario.processes):
        # a package it runs is missing: the recording's `packages` event (the contract's names,
        # grader.analyze.contract) then speaks of the others, which differ from student to student
        for name, pkg in sorted(build.packages.items()):
            h.update(f"{name}:{pkg.status}:{','.join(sorted(pkg.executables))}".encode())
    return h.hexdigest()[:24]


class RecordingCache:
    """``<root>/<key>/``: a finished scenario folder plus ``source.json`` (who recorded it)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    @contextlib.contextmanager
    def locked(self, key: str) -> Iterator[None]:
        self.root.mkdir(parents=True, exist_ok=True)
        with open(self.root / f"{key}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            yield

    def get(self, key: str, dest: Path) -> dict[str, Any] | None:
        """Copy the recording into ``dest``; its source record, or None when there is none."""
        entry = self.root / key
        source = entry / "source.json"
        if not source.is_file():
            return None
        if dest.exists():
            shutil.rmtree(dest)
        shutil.copytree(entry, dest, ignore=shutil.ignore_patterns("source.json"))
        return json.loads(source.read_text())

    def put(self, key: str, folder: Path, submission: str) -> None:
        """Keep a finished scenario folder (atomically: a half-copied entry is never used)."""
        tmp = self.root / f".{key}.{os.getpid()}.tmp"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        for name in RECORDING:
            src = folder / name
            if src.is_dir():
                shutil.copytree(src, tmp / name)
            elif src.is_file():
                shutil.copy2(src, tmp / name)
        (tmp / "source.json").write_text(json.dumps({"submission": submission, "key": key,
                                                     "recorded": time.strftime("%Y-%m-%dT%H:%M:%S")}))
        final = self.root / key
        shutil.rmtree(final, ignore_errors=True)
        os.replace(tmp, final)


def reusable(record: dict[str, Any]) -> bool:
    """A recording worth keeping: the scenario ran to its end without a grader-side problem."""
    return not record.get("errors") and not record.get("interrupted") and bool(record.get("steps"))
