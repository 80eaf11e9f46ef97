"""Which ROS 2 is in use, and the environment every child ROS process gets.

The grader runs on two kinds of machines: a fresh one where ROS 2 Jazzy comes from PyPI wheels
into ``.venv``, and a lab machine with ``/opt/ros/jazzy`` sourced. Both end up as "the Python
running the grader can import rclpy"; this module describes which one it is and builds child
environments (domain, localhost-only discovery, overlay prefixes of built workspaces).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Iterable, Mapping

FASTDDS_PROFILE = Path(__file__).resolve().parent / "dds" / "fastdds_profile.xml"
PY_SITE = f"lib/python{sys.version_info.major}.{sys.version_info.minor}/site-packages"


def ros_mode() -> str:
    """``wheels`` when rclpy lives inside this venv, else ``system``."""
    try:
        import rclpy  # noqa: PLC0415
    except ImportError:
        return "missing"
    return "wheels" if Path(rclpy.__file__).resolve().is_relative_to(Path(sys.prefix).resolve()) \
        else "system"


def ros_info() -> dict[str, str]:
    """Facts for `grader doctor` and result.json: mode, distro, rclpy version, RMW, python."""
    from importlib import metadata  # noqa: PLC0415

    info = {"mode": ros_mode(), "python": sys.version.split()[0], "prefix": sys.prefix}
    info["distro"] = os.environ.get("ROS_DISTRO") or ("jazzy" if info["mode"] == "wheels" else "?")
    for dist in ("ros-jazzy-rclpy", "rclpy"):
        try:
            info["rclpy"] = metadata.version(dist)
            break
        except metadata.PackageNotFoundError:
            continue
    else:
        info["rclpy"] = "?"
    info["rmw"] = os.environ.get("RMW_IMPLEMENTATION") or "rmw_fastrtps_cpp"
    return info


def _prepend(env: dict[str, str], var: str, parts: Iterable[str]) -> None:
    new = [p for p in parts if p]
    old = [p for p in env.get(var, "").split(os.pathsep) if p and p not in new]
    if new or old:
        env[var] = os.pathsep.join(new + old)


#: the students' Python trees, for a grader process that imports their interface types: appended
#: to ``sys.path`` after start-up (:func:`add_student_paths`) instead of being on ``PYTHONPATH``
STUDENT_PATH_VAR = "GRADER_STUDENT_PYTHONPATH"
#: the students' trees :func:`add_student_paths` added in this process (kept out of grader processes)
_STUDENT_PATHS: list[str] = []


def trusted_env(env: Mapping[str, str], prefixes: Iterable[Path]) -> dict[str, str]:
    """``env`` for a grader process (the scenario child, the simulator), which runs outside the
    students' jail: the students' Python trees (``<prefix>/lib/pythonX.Y/site-packages`` of their
    builds) leave ``PYTHONPATH`` for :data:`STUDENT_PATH_VAR`.

    On ``PYTHONPATH`` they come before the venv, so Python would run a ``sitecustomize.py`` or
    ``usercustomize.py`` a student's package installs there at the start of every grader process
    (as the grader's user: root on Gradescope), and a student's module named like one the grader
    imports (``yaml``, ``numpy``) would shadow it.
    """
    out = dict(env)
    roots = [Path(p) for p in [*prefixes, *_STUDENT_PATHS]]
    theirs, ours = [], []
    for entry in filter(None, out.get("PYTHONPATH", "").split(os.pathsep)):
        path = Path(entry)
        (theirs if any(path == r or r in path.parents for r in roots) else ours).append(entry)
    if ours:
        out["PYTHONPATH"] = os.pathsep.join(ours)
    else:
        out.pop("PYTHONPATH", None)
    if theirs:
        out[STUDENT_PATH_VAR] = os.pathsep.join(theirs)
    return out


def add_student_paths() -> None:
    """In a grader process started with :func:`trusted_env`: make the students' interface types
    importable, after everything of the grader's own (so nothing of theirs shadows it), and give
    the processes it starts the build's ``PYTHONPATH`` back."""
    theirs = [e for e in os.environ.pop(STUDENT_PATH_VAR, "").split(os.pathsep) if e]
    _STUDENT_PATHS.extend(theirs)
    for entry in theirs:
        if entry not in sys.path:
            sys.path.append(entry)
    # what this process starts gets the build's environment as colcon's setup.bash gives it (the
    # students' trees first); RosGraph takes them out again for the grader's own processes
    if theirs:
        os.environ["PYTHONPATH"] = os.pathsep.join([*theirs, *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))])


def child_env(*, domain_id: int | None = None, prefixes: Iterable[Path] = (),
              base: Mapping[str, str] | None = None,
              extra: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment for a child ROS process.

    ``prefixes`` are install prefixes of built workspaces (``install/<pkg>``, isolated layout),
    innermost first; this is what sourcing ``install/setup.bash`` would add.
    """
    env = dict(os.environ if base is None else base)
    prefixes = [Path(p) for p in prefixes]
    venv = Path(sys.prefix)
    _prepend(env, "AMENT_PREFIX_PATH", [str(p) for p in prefixes] + [str(venv)])
    _prepend(env, "CMAKE_PREFIX_PATH", [str(p) for p in prefixes] + [str(venv)])
    _prepend(env, "PYTHONPATH", [str(p / PY_SITE) for p in prefixes if (p / PY_SITE).is_dir()])
    # the venv is an install prefix too: our turtlesim's typesupport libraries are in venv/lib (the
    # wheels' start-up hook adds it; a sourced system ROS 2 does not, and turtlesim fails to load)
    _prepend(env, "LD_LIBRARY_PATH", [str(p / "lib") for p in [*prefixes, venv] if (p / "lib").is_dir()])
    _prepend(env, "PATH", [str(venv / "bin")])
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; would override the range
    env.pop("ROS_STATIC_PEERS", None)
    if not env.get("FASTRTPS_DEFAULT_PROFILES_FILE") and not env.get("FASTDDS_DEFAULT_PROFILES_FILE"):
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(FASTDDS_PROFILE)   # quicker discovery
    env["PYTHONUNBUFFERED"] = "1"        # student print() lines reach the log as they happen
    env["RCUTILS_COLORIZED_OUTPUT"] = "0"
    env.setdefault("RCUTILS_LOGGING_BUFFERED_STREAM", "0")
    if extra:
        env.update(extra)
    return env
