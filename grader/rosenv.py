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
#: the reference simulator's own: the same discovery, readers that repair a lost request at once
SIMULATOR_DDS_PROFILE = FASTDDS_PROFILE.with_name("fastdds_profile_simulator.xml")
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


#: the trusted builds' Python trees (``grader.workspace.trusted_interfaces``), for a grader process
#: that imports the students' interface types: appended to ``sys.path`` after start-up
#: (:func:`add_interface_paths`), so no module of theirs shadows one of the grader's
INTERFACE_PATH_VAR = "GRADER_INTERFACE_PYTHONPATH"


def _under(entry: str, roots: list[Path]) -> bool:
    path = Path(entry)
    return any(path == r or r in path.parents for r in roots)


def trusted_env(env: Mapping[str, str], prefixes: Iterable[Path],
                interfaces: Iterable[Path] = ()) -> dict[str, str]:
    """``env`` for a grader process (the scenario child, the simulator), which runs outside the
    students' jail as the grader's user (root on Gradescope): nothing of the students' builds
    (``prefixes``) may be loaded in it.

    * ``PYTHONPATH`` loses their Python trees: before the venv, Python would run a
      ``sitecustomize.py`` or ``.pth`` file a student's package installs there at start-up, a
      module named like one the grader imports (``yaml``, ``numpy``) would shadow it, and their
      interface packages may hold any Python their build installed. The student types come
      from ``interfaces`` instead, the grader's own builds of their definitions, appended to
      ``sys.path`` at start-up (:data:`INTERFACE_PATH_VAR`, :func:`add_interface_paths`).
    * ``LD_LIBRARY_PATH`` loses their ``lib`` folders (a library there named like one of ROS
      would be loaded, and the generated modules' typesupport libraries are found there) and
      gets the trusted builds' ones, last.
    * ``AMENT_PREFIX_PATH`` and ``CMAKE_PREFIX_PATH`` keep their prefixes (package share
      lookups) but last, after the system's and the trusted builds' (whose definitions the
      recorder writes into the bag): a package of theirs named like one of ROS (``turtlesim``)
      is never found before it.
    """
    out = dict(env)
    roots = [Path(p) for p in prefixes]
    trusted = [Path(p) for p in interfaces]

    def entries(var: str) -> list[str]:
        return [e for e in out.get(var, "").split(os.pathsep) if e]

    def put(var: str, parts: list[str]) -> None:
        if parts:
            out[var] = os.pathsep.join(dict.fromkeys(parts))
        else:
            out.pop(var, None)

    put("PYTHONPATH", [e for e in entries("PYTHONPATH") if not _under(e, roots)])
    put("LD_LIBRARY_PATH", [e for e in entries("LD_LIBRARY_PATH") if not _under(e, roots)]
        + [str(p / "lib") for p in trusted if (p / "lib").is_dir()])
    for var in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
        theirs = [e for e in entries(var) if _under(e, roots)]
        put(var, [e for e in entries(var) if e not in theirs] + [str(p) for p in trusted] + theirs)
    sites = [str(p / PY_SITE) for p in trusted if (p / PY_SITE).is_dir()]
    if sites:
        out[INTERFACE_PATH_VAR] = os.pathsep.join(sites)
    else:
        out.pop(INTERFACE_PATH_VAR, None)
    return out


def add_interface_paths() -> None:
    """In a grader process started with :func:`trusted_env`: make the students' interface types
    (the grader's builds of them) importable, after everything of the grader's own."""
    for entry in filter(None, os.environ.pop(INTERFACE_PATH_VAR, "").split(os.pathsep)):
        if entry not in sys.path:
            sys.path.append(entry)


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


def simulator_env(env: Mapping[str, str]) -> dict[str, str]:
    """What the reference simulator's process gets on top of the graph's ``env``: its own Fast DDS
    profile (``SIMULATOR_DDS_PROFILE``: readers that repair a request lost to discovery at once,
    so a lockstep tick does not go on before it) where the graph uses the grader's profile; a
    profile of the machine's own (a lab's FASTRTPS_DEFAULT_PROFILES_FILE) is left as it is."""
    if env.get("FASTDDS_DEFAULT_PROFILES_FILE") or env.get("FASTRTPS_DEFAULT_PROFILES_FILE") != str(FASTDDS_PROFILE):
        return {}
    return {"FASTRTPS_DEFAULT_PROFILES_FILE": str(SIMULATOR_DDS_PROFILE)}
