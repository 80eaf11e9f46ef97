"""Reusing a scenario's recording when nothing it runs has changed.

A scenario's bag depends only on what runs in it: the rubric's scenario (its model, as JSON), the
source of every package it starts and of the workspace packages those depend on (and their
build status), the files it replays, how it is run (the sandbox's active protections, the time
scale and the rates its watchdog expects), and the grader and what it runs on. When all of these
are identical to a run already recorded (a template package untouched by half the class, a
student re-running ``grader check`` after fixing one node), the recording is copied instead of
run again. The result says which scenarios were reused and from where (never silent);
``--no-reuse`` turns it off.

"The grader" is not a version someone bumps: the key holds the digest of every grader file that
takes part in making a recording (``grader.cache.code.recording_code``: the import closure of the
scenario child, its parent side, the launch loader and the build, with the Fast DDS profiles,
the launch stand-ins and the turtlesim interfaces) and of the ROS 2 and Python it runs on
(``grader.cache.environment.runtime``: distribution, rclpy, RMW, Fast DDS, every ROS package and
Python distribution installed). An upgrade, or a developer's edit of the driver, records again.
Every recording notes who made it (``made_by``: grader version, code and environment digests,
ROS), in its ``scenario.json`` and in the cache entry, so a reused one names its origin and a
regrade by another grader can say which grades rest on recordings it did not make.

Recordings live beside the build cache (``<cache>/recordings/<key>/``); a per-key lock makes a
second submission with the same key wait for the first one's recording instead of running it
twice, and keeps ``grader cache prune`` off an entry while it is read or written.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import threading
import shutil
import time
from pathlib import Path
from typing import Any, Iterator

from grader.contracts.scenario_record import ScenarioRecord
from grader import __version__
from grader.cache import locks
from grader.contracts.output_folder import BAG_DIR, CANVAS_PNG, LOGS_DIR, RUN_JSON, SCENARIO_JSON, SCENARIO_LOG
from grader.cache.code import recording_code
from grader.cache.environment import runtime
from grader.grading.scenario_packages import packages_run, workspace_packages
from grader.grading.starvation import record_unstarved
from grader.grading.timescale import ScaledRecording
from grader.scenario.model import Scenario
from grader.sandbox import summary
from grader.scenario import resolve

#: files of a scenario folder that make up its recording
RECORDING = (BAG_DIR, LOGS_DIR, CANVAS_PNG, SCENARIO_JSON, RUN_JSON, SCENARIO_LOG)


def _tree_digest(path: Path) -> str:
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for f in files:
        h.update(str(f.relative_to(path) if path.is_dir() else f.name).encode() + b"\0")
        h.update(f.read_bytes())
    return h.hexdigest()


def made_by() -> dict[str, str]:
    """Who makes recordings in this process: what ``scenario.json`` and ``result.json`` keep."""
    env = runtime()
    return {"grader": __version__, "code": recording_code()[:16], "environment": env["digest"][:16],
            "ros": f"{env['ros']} ({env['mode']})", "rclpy": env["rclpy"], "rmw": env["rmw"], "dds": env["dds"]}


def scenario_key(scenario_id: str, scenario: Scenario, build: Any, settings: str = "") -> str | None:
    """The recording's identity, or None when it cannot be reused (no build). ``settings``: how
    the recording was made beyond the scenario (e.g. its time scale)."""
    if build is None:
        return None
    packages = workspace_packages(Path(build.root) / "src")
    closure = packages_run(scenario, packages)
    h = hashlib.sha256(f"{recording_code()}:{runtime()['digest']}:{settings}:{scenario_id}".encode())
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
        """The key's lock, held while its entry is looked up, recorded and copied; taking it
        marks the entry used (``grader.cache.locks``)."""
        lock = self.root / f"{key}.lock"
        with locks.locked(lock):
            locks.touch(lock)
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
        found: dict[str, Any] = json.loads(source.read_text())
        return found

    def put(self, key: str, folder: Path, submission: str) -> None:
        """Keep a finished scenario folder (atomically: a half-copied entry is never used)."""
        tmp = self.root / f".{key}.{os.getpid()}.{threading.get_ident()}.tmp"   # scenarios run in threads
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        for name in RECORDING:
            src = folder / name
            if src.is_dir():
                shutil.copytree(src, tmp / name)
            elif src.is_file():
                shutil.copy2(src, tmp / name)
        (tmp / "source.json").write_text(json.dumps({"submission": submission, "key": key,
                                                     "recorded": time.strftime("%Y-%m-%dT%H:%M:%S"),
                                                     "made_by": made_by()}))
        final = self.root / key
        shutil.rmtree(final, ignore_errors=True)
        os.replace(tmp, final)


def reusable(record: ScenarioRecord) -> bool:
    """A recording worth keeping: the scenario ran to its end without a grader-side problem."""
    return not record.errors and not record.interrupted and bool(record.steps)


def recording_settings(time_scale: float = 1.0, rates: tuple = (), run: int = 1) -> str:
    """What, besides the inputs, changes a recording: the sandbox's active protections (a
    recording made with fewer of them is not reused where more are active), the time scale and
    the rates the watchdog of a faster run expects (the rubric's ``publish_rate`` items), and
    which run of a repeated scenario it is (run ``run`` > 1 is a recording of its own)."""
    info = summary()
    scaled = f";time_scale={time_scale:g};rates={sorted(map(repr, rates))}" if time_scale > 1 else ""
    again = f";run={run}" if run > 1 else ""
    return f"sandbox={info['mode']}:{','.join(sorted(info['active']))}{scaled}{again}"


def _note_recording(folder: Path, record: ScenarioRecord, key: str | None) -> ScenarioRecord:
    """Keep the recording's key and maker in the record and its ``scenario.json`` (a copy made
    from the cache carries the maker of the original)."""
    note = {"key": key, "made_by": made_by()}
    ScenarioRecord.amend(folder / SCENARIO_JSON, {"recording": note})
    return record.amended({"recording": note})


def record_or_reuse(sid: str, sc_id: str, scenario: Scenario, build: Any, folder: Path, slots: Any,
                    recordings: Path | None, time_scale: float = 1.0, rates: tuple = (),
                    run: int = 1) -> ScenarioRecord:
    """One recording of a scenario into ``folder``: copied from an identical earlier recording
    under ``recordings`` (None: ``--no-reuse``), or run within one of ``slots`` (and made again
    while the machine starves it, ``grader.grading.starvation``); returns its record. Run ``run``
    > 1 of a repeated scenario is a recording of its own (its own key)."""
    def make() -> ScenarioRecord:
        with slots.taken():
            return record_unstarved(ScaledRecording(resolve(sc_id, scenario, build), folder, time_scale,
                                                    build, rates), folder)

    key = scenario_key(sc_id, scenario, build, settings=recording_settings(time_scale, rates, run))
    if key is None or recordings is None:
        return _note_recording(folder, make(), key)
    cache = RecordingCache(recordings)
    with cache.locked(key):
        t0 = time.monotonic()
        source = cache.get(key, folder)
        if source is not None:
            reused = ScenarioRecord.read(folder / SCENARIO_JSON).amended(
                {"reused": {"from": source.get("submission"), "key": key, "recorded": source.get("recorded"),
                            "made_by": source.get("made_by")},
                 "parent_wall_s": round(time.monotonic() - t0, 3)}, str(folder / SCENARIO_JSON))
            reused.write(folder / SCENARIO_JSON)
            return reused
        record = _note_recording(folder, make(), key)
        if reusable(record):
            cache.put(key, folder, sid)
        return record
