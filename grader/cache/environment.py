"""What besides the grader's own code shapes a cache entry: the ROS 2 and Python it runs on, and
the tools a build runs.

A recording is made by rclpy over an RMW and Fast DDS, with message packages, the ``mcap`` writer
and numpy in the grader's processes, and a student's nodes may import anything installed in the
same environment. A build runs colcon (a set of Python distributions), CMake, a C/C++ compiler,
Ninja, setuptools and the ament/rosidl CMake code of the ROS installed. So the keys carry:

* ``runtime()``: the ROS distribution (``ROS_DISTRO``, wheels or a sourced system ROS), the RMW
  (``RMW_IMPLEMENTATION``), the version of every ROS package in the ament prefixes the grader
  uses (``share/<pkg>/package.xml``: rclpy, the RMW, the message packages, ament, rosidl...),
  Fast DDS's version (its CMake version file: it has no ``package.xml``), the Python version and
  every Python distribution importable here (the ``*.dist-info`` names on ``sys.path``: name and
  version, colcon's plugins and setuptools included). An upgrade of any of them, e.g. by
  ``grader setup`` after new pins, changes the digest;
* ``build_tools()``: in addition, the first line of ``cmake --version``, the C and C++
  compilers' (``$CC``/``$CXX`` or ``cc``/``c++``, as CMake picks them) and ``ninja --version``,
  found on the PATH colcon gets.

Measured on the 2-core development machine: ~5 ms for the ROS packages and distributions
(directory listings and 90 small ``package.xml`` reads), ~40 ms (wall) for the four
``--version`` calls; each once per process.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from grader.rosenv import child_env

_VERSION = re.compile(rb"<version>\s*([^<\s]+)\s*</version>")
_CMAKE_VERSION = re.compile(r'set\(PACKAGE_VERSION\s+"([^"]+)"\)')
DEFAULT_RMW = "rmw_fastrtps_cpp"


def ament_prefixes() -> list[Path]:
    """The prefixes a child ROS process searches: ``AMENT_PREFIX_PATH`` and the venv."""
    parts = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [Path(p) for p in dict.fromkeys([*parts, sys.prefix])]


def ros_packages(prefixes: list[Path] | None = None) -> dict[str, str]:
    """``{package: version}`` of every ROS package installed in ``prefixes`` (the first wins, as
    for the ament index)."""
    out: dict[str, str] = {}
    for prefix in prefixes if prefixes is not None else ament_prefixes():
        for manifest in sorted(prefix.glob("share/*/package.xml")):
            name = manifest.parent.name
            if name in out:
                continue
            try:
                found = _VERSION.search(manifest.read_bytes())
            except OSError:
                continue
            out[name] = found.group(1).decode() if found else "?"
    return out


def fastdds_version(prefixes: list[Path] | None = None) -> str:
    """Fast DDS's version from its CMake package version file ("?" when not found)."""
    for prefix in prefixes if prefixes is not None else ament_prefixes():
        for name in ("fastdds", "fastrtps"):
            for f in sorted(prefix.glob(f"share/{name}/cmake/{name}-config-version.cmake")):
                found = _CMAKE_VERSION.search(f.read_text(errors="replace"))
                if found:
                    return f"{name} {found.group(1)}"
    return "?"


def python_distributions() -> list[str]:
    """Every distribution importable here, as its metadata folder names it (``mcap-1.3.0``)."""
    names: set[str] = set()
    for entry in sys.path:
        try:
            listing = os.listdir(entry or ".")
        except OSError:
            continue
        names.update(n.rsplit(".", 1)[0] for n in listing if n.endswith((".dist-info", ".egg-info")))
    return sorted(names)


def _digest(facts: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps(facts, sort_keys=True).encode()).hexdigest()


def ros_mode() -> str:
    """``wheels`` when rclpy lives inside this venv, ``system`` when elsewhere, else ``missing``:
    what ``grader.rosenv.ros_mode`` says, found without importing rclpy (~85 ms of CPU)."""
    spec = importlib.util.find_spec("rclpy")
    if spec is None or not spec.origin:
        return "missing"
    return "wheels" if Path(spec.origin).resolve().is_relative_to(Path(sys.prefix).resolve()) else "system"


@functools.lru_cache(maxsize=None)
def runtime() -> dict[str, Any]:
    """The ROS 2 and Python a recording is made with; ``digest`` over all of it."""
    packages = ros_packages()
    rmw = os.environ.get("RMW_IMPLEMENTATION") or DEFAULT_RMW
    facts: dict[str, Any] = {
        "ros": os.environ.get("ROS_DISTRO") or "jazzy", "mode": ros_mode(),
        "rclpy": packages.get("rclpy", "?"), "rmw": f"{rmw} {packages.get(rmw, '?')}",
        "dds": fastdds_version(), "python": sys.version.split()[0],
        "ros_packages": packages, "python_distributions": python_distributions()}
    return {**facts, "digest": _digest(facts)}


def _first_line(argv: list[str], path: str) -> str:
    exe = shutil.which(argv[0], path=path)
    if exe is None:
        return "missing"
    try:
        run = subprocess.run([exe, *argv[1:]], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError) as exc:
        return f"unknown ({exc.__class__.__name__})"
    return next((ln.strip() for ln in (run.stdout + run.stderr).splitlines() if ln.strip()), "?")


@functools.lru_cache(maxsize=None)
def build_tools() -> dict[str, Any]:
    """``runtime()`` plus the versions of CMake, the compilers and Ninja a build runs."""
    path = child_env().get("PATH", "")
    tools = {"cmake": _first_line(["cmake", "--version"], path),
             "cc": _first_line([os.environ.get("CC") or "cc", "--version"], path),
             "c++": _first_line([os.environ.get("CXX") or "c++", "--version"], path),
             "ninja": _first_line(["ninja", "--version"], path)}
    facts = {"runtime": runtime()["digest"], **tools}
    return {**tools, "digest": _digest(facts)}
