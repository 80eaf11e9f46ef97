"""Helpers of the sandbox tests: scenarios run for real through ``run_scenario`` with the hostile
programs of this folder as student processes, snapshots of files no student may touch, and a
search of /proc for the processes a test started."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import pytest

from grader.sandbox import protections

HERE = Path(__file__).parent


def require_protections(*names: str) -> None:
    missing = [p for p in protections() if p.name in names and not p.active]
    if missing:
        pytest.skip("sandbox protections unavailable here: " + "; ".join(f"{p.name} ({p.detail})" for p in missing))


def processes_with(token: str) -> list[int]:
    """Live (not zombie) processes whose command line holds ``token``."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if token.encode() in (d / "cmdline").read_bytes():
                    stat = (d / "stat").read_text()
                    if stat.rsplit(")", 1)[1].split()[0] != "Z":
                        found.append(int(d.name))
            except OSError:
                continue
    return found


def snapshot(root: Path) -> dict[str, tuple[int, int, str]]:
    """Every file and directory under ``root``: size, mtime and content hash."""
    out = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""
        out[str(p.relative_to(root))] = (st.st_size, st.st_mtime_ns, digest)
    return out


def run_hostile(prefix: Path, out: Path, procs: dict[str, list[str]], *, wait_s: float = 6.0,
                sim: bool = False, memory_mb: int | None = None, env: dict[str, str] | None = None) -> dict[str, Any]:
    """One scenario whose student processes are ``SCRIPT ARGS`` from the fake build's lib folder
    (``procs``: name -> [script, args...])."""
    from grader.scenario import run_scenario
    from grader.scenario.model import Scenario
    from grader.scenario.runspec import LaunchedProcess, ScenarioRun

    lib = prefix / "lib" / "hostile"
    scenario = Scenario.model_validate({
        "sim": sim, "record": ["/student_chatter", "/turtle1/pose"] if sim else ["/student_chatter"],
        "processes": [{"name": n, "package": "hostile", "module": "hostile:main", "env": env or {}}
                      for n in procs],
        "steps": [{"id": "run", "wait": wait_s}],
        "limits": {"wall_s": 120, **({"memory_mb": memory_mb} if memory_mb else {})}})
    launched = {n: (LaunchedProcess(name=n, process=n, argv=(sys.executable, str(lib / args[0]), *args[1:])),)
                for n, args in procs.items()}
    run = ScenarioRun(id="hostile", scenario=scenario, launched=launched, prefixes=(str(prefix),))
    return run_scenario(run, out).to_json()


def log(out: Path, name: str, stream: str = "stdout") -> str:
    path = out / "logs" / f"{name}.{stream}.log"
    return path.read_text(errors="replace") if path.exists() else ""


def events(out: Path) -> list[dict]:
    from grader.bag.frames import load_frames

    frames = load_frames(out / "bag", topics=["/grader/events"])
    return [json.loads(d) for d in frames["/grader/events"]["data"]] if "/grader/events" in frames else []
