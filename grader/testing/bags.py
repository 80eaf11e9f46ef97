"""Pytest plugin for bags: committed fixture bags as DataFrames, and replaying bags into a graph.

Enable with ``pytest_plugins = ["grader.testing.bags"]`` in ``tests/conftest.py``. Fixtures:

* ``bag_frames(name, topics=None)`` → ``dict[str, DataFrame]`` of ``fixtures/bags/<name>``
  (cached per session; analyzer tests never need ROS),
* ``fixture_bag(name)`` → the bag directory path,
* ``replay_bag(bag, graph=None, **options)`` → a :class:`Replay` running ``grader replay`` as a
  process in ``graph`` (a :class:`grader.runner.RosGraph`; a private one when omitted), stopped at
  teardown.

Also :func:`build_interface_package`: build an interface package (like a student's) into a
cached prefix, for tests that need custom message types.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest

from grader.runner import ProcessSpec, RosGraph

ROOT = Path(__file__).resolve().parents[2]
FIXTURE_BAGS = ROOT / "fixtures" / "bags"


def fixture_bag_path(name: str) -> Path:
    """``fixtures/bags/<name>``; a clear failure names the bags that exist."""
    path = FIXTURE_BAGS / name
    if not path.is_dir():
        have = sorted(p.name for p in FIXTURE_BAGS.iterdir() if p.is_dir()) if FIXTURE_BAGS.is_dir() else []
        raise FileNotFoundError(f"no fixture bag {name!r} in {FIXTURE_BAGS} (have: {', '.join(have) or 'none'}); "
                                "run `python fixtures/bags/regenerate.py`")
    return path


_FRAMES_CACHE: dict[tuple[str, tuple[str, ...] | None], dict] = {}


def load_fixture_frames(name: str, topics: list[str] | None = None) -> dict:
    """DataFrames of a fixture bag; each call gets its own copies (tests may mutate them)."""
    from grader.bag.frames import load_frames  # noqa: PLC0415 - bag.frames loads pandas, numpy (424 ms CPU), only on this path

    key = (name, tuple(topics) if topics else None)
    if key not in _FRAMES_CACHE:
        _FRAMES_CACHE[key] = load_frames(fixture_bag_path(name), topics)
    return {k: v.copy() for k, v in _FRAMES_CACHE[key].items()}


@pytest.fixture
def bag_frames() -> Callable[..., dict]:
    """``bag_frames("circle_pose")`` → ``{topic: DataFrame}`` of a committed fixture bag."""
    return load_fixture_frames


@pytest.fixture
def fixture_bag() -> Callable[[str], Path]:
    return fixture_bag_path


@dataclass
class Replay:
    """A running ``grader replay`` process."""

    process: Any          # grader.runner.ManagedProcess
    graph: Any            # grader.runner.RosGraph

    @property
    def domain_id(self) -> int:
        return self.graph.domain_id

    def wait_ready(self, timeout: float = 20.0) -> None:
        _wait_line(self.process, "READY", timeout)

    def wait_done(self, timeout: float = 60.0) -> int:
        """Wait for the last message; returns how many were published."""
        line = _wait_line(self.process, "DONE", timeout)
        return int(line.split()[1])


def _wait_line(proc: Any, prefix: str, timeout: float) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for line in proc.output().splitlines():
            if line.startswith(prefix):
                return line
        if not proc.alive():
            break
        time.sleep(0.02)
    for line in proc.output().splitlines():
        if line.startswith(prefix):
            return line
    raise AssertionError(f"replay never printed {prefix} (rc={proc.returncode}); stderr: "
                         f"{proc.errors()[-1500:]}")


def replay_argv(bag: Path | str, *, topics: list[str] | None = None, rate: float = 1.0,
                remap: dict[str, str] | None = None, loop: bool = False, start_offset: float = 0.0,
                clock_hz: float = 0.0, wait_subscribers: int = 0, delay: float = 0.0) -> list[str]:
    argv = [sys.executable, "-m", "grader.bag.replay", str(bag), "--rate", str(rate),
            "--start-offset", str(start_offset), "--wait-subscribers", str(wait_subscribers),
            "--delay", str(delay)]
    if topics:
        argv += ["--topics", *topics]
    for old, new in (remap or {}).items():
        argv += ["--remap", f"{old}:={new}"]
    if loop:
        argv.append("--loop")
    if clock_hz:
        argv += ["--clock", str(clock_hz)]
    return argv


@pytest.fixture
def replay_bag(tmp_path: Path) -> Iterator[Callable[..., Replay]]:
    """Start ``grader replay`` for a bag (fixture name or path) in a graph; stopped afterwards."""
    own: list[Any] = []
    started: list[Any] = []

    def start(bag: str | Path, graph: Any = None, name: str = "replay", **options: Any) -> Replay:
        path = Path(bag) if Path(bag).is_dir() else fixture_bag_path(str(bag))
        if graph is None:
            graph = RosGraph(workdir=tmp_path / f"replay-graph-{len(own)}")
            own.append(graph)
        proc = graph.start(ProcessSpec(name=name, argv=replay_argv(path, **options)))
        started.append(proc)
        return Replay(proc, graph)

    try:
        yield start
    finally:
        for proc in started:
            proc.stop()
        for graph in own:
            graph.close()


def build_interface_package(src: Path, cache_root: Path | None = None) -> Path:
    """Build an ament_cmake interface package into a prefix cached by its sources' hash.

    Same recipe as grader/bootstrap.py uses for turtlesim (CMake + Ninja against the venv).
    Returns the install prefix (``share/<pkg>``, ``lib``, ``lib/pythonX.Y/site-packages``).
    """
    src = Path(src)
    h = hashlib.sha256()
    for f in sorted(p for p in src.rglob("*") if p.is_file()):
        h.update(str(f.relative_to(src)).encode())
        h.update(f.read_bytes())
    h.update(sys.prefix.encode())
    cache_root = Path(cache_root or ROOT / ".cache" / "test-interfaces")
    prefix = cache_root / f"{src.name}-{h.hexdigest()[:16]}"
    stamp = prefix / ".built"
    if stamp.exists():
        return prefix
    build = prefix.with_name(prefix.name + "-build")
    shutil.rmtree(build, ignore_errors=True)
    shutil.rmtree(prefix, ignore_errors=True)
    venv = Path(sys.prefix)
    env = dict(os.environ)
    for var in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
        env[var] = os.pathsep.join(p for p in [str(venv), env.get(var, "")] if p)
    env["PATH"] = os.pathsep.join([str(venv / "bin"), env.get("PATH", "")])
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    steps = [
        ["cmake", "-S", str(src), "-B", str(build), *gen, f"-DCMAKE_INSTALL_PREFIX={prefix}",
         f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF"],
        ["cmake", "--build", str(build), "--parallel", "2"],
        ["cmake", "--install", str(build)],
    ]
    for cmd in steps:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{(proc.stdout + proc.stderr)[-3000:]}")
    shutil.rmtree(build, ignore_errors=True)
    stamp.write_text("ok\n")
    return prefix
