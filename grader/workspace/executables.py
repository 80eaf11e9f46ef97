"""Executables found and started the way ``ros2 run`` and ``ros2 launch`` find and start them.

The one place where "package P's executable E" becomes a file and a command line: rubric
``executable:`` processes, launch-file ``Node(package=..., executable=...)``, ``grader build``'s
listing and every "has no executable" message use it. ROS knows nothing of setup.py entry points
here: ``ros2 run`` (ros2run/ros2pkg ``get_executable_paths``) takes the package's prefix from the
ament index (the first prefix on ``AMENT_PREFIX_PATH`` with
``share/ament_index/resource_index/packages/<P>``), then every executable file below
``<prefix>/lib/<P>/`` (folders starting with ``.`` skipped) whose name is E; ``launch_ros``'s
``Node`` (``ExecutableInPackage``) looks in ``<prefix>/lib/<P>/`` itself only. So an ament_python
console script, a CMake ``install(PROGRAMS ...)`` script and a C++ binary are all found alike.

Starting one is what ``exec`` does with it: a binary runs directly; a script runs by its ``#!``
line. A Python ``#!`` (``/usr/bin/env python3``, ``/usr/bin/python3``, the absolute interpreter
setuptools writes) means "the ROS Python" on a ROS machine, the one with ``rclpy``: here that is
the grader's own interpreter (the venv's, or the sourced ROS's), so such a script runs as
``<that python> [its flags] SCRIPT ARGS`` and a ``/usr/bin/python3`` without ROS never gets it.
A console script costs its process ~40 ms more CPU than importing the entry point directly did
(setuptools' script looks its entry point up with ``importlib.metadata``; measured: median 88 ms
against 47 ms for a script printing "hello", next to ~370 ms for an rclpy node's own start-up);
that is what ``ros2 run`` costs too.
"""

from __future__ import annotations

import os
import re
import shlex
import sys
from pathlib import Path
from typing import Mapping, Sequence

from grader.errors import GraderError

INDEX = Path("share") / "ament_index" / "resource_index" / "packages"
_PYTHON = re.compile(r"python(3(\.\d+)?)?")


def search_path(env: Mapping[str, str]) -> list[Path]:
    """The prefixes ``ros2 run`` searches: ``AMENT_PREFIX_PATH``, in order."""
    return [Path(p) for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]


def package_prefix(package: str, prefixes: Sequence[Path]) -> Path | None:
    """The first prefix whose ament index holds ``package`` (``ros2 pkg prefix``), else None."""
    for prefix in prefixes:
        if (Path(prefix) / INDEX / package).is_file():
            return Path(prefix)
    return None


def executable_paths(package: str, prefix: Path, *, nested: bool = True) -> list[Path]:
    """Executable files of ``package`` at ``prefix`` (``ros2 pkg executables --full-path``).

    ``nested=False``: ``<prefix>/lib/<package>/`` itself only, as a launch file's ``Node`` sees it.
    """
    base = Path(prefix) / "lib" / package
    out: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(base):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".")) if nested else []
        out += [Path(dirpath) / f for f in sorted(filenames) if os.access(Path(dirpath) / f, os.X_OK)]
    return out


def stray_executables(package: str, prefix: Path) -> list[str]:
    """Executables the package installed under ``<prefix>/lib/<other>/`` (``lib/<other>/<name>``):
    ``ros2 run`` finds none of them under either name. A package renamed in ``setup.py`` whose
    ``setup.cfg`` still says ``script_dir=$base/lib/<old name>`` leaves its nodes there."""
    lib = Path(prefix) / "lib"
    others = sorted(d.name for d in lib.iterdir() if d.is_dir() and d.name != package
                    and not d.name.startswith(("python", "."))) if lib.is_dir() else []
    return [str(p.relative_to(lib)) for other in others for p in executable_paths(other, prefix)]


def listing(package: str, prefix: Path | None) -> list[str]:
    """Names ``ros2 pkg executables <package>`` prints (empty when the package is not found)."""
    return sorted(p.name for p in executable_paths(package, prefix)) if prefix is not None else []


def find_executable(package: str, name: str, prefixes: Sequence[Path], *, nested: bool = True) -> Path:
    """The file ``ros2 run package name`` runs (``nested=False``: the one ``launch_ros`` runs).

    Raises :class:`GraderError` with what ``ros2 run`` would say, and what the student can do.
    """
    prefix = package_prefix(package, prefixes)
    if prefix is None:
        raise GraderError(f"package '{package}' not found: no install prefix has it in the ament index "
                          f"({INDEX}/{package}), so `ros2 run` and `ros2 launch` cannot find it")
    hits = [p for p in executable_paths(package, prefix, nested=nested) if p.name == name]
    if len(hits) > 1:
        where = ", ".join(str(p.relative_to(prefix)) for p in hits)
        raise GraderError(f"package '{package}' has more than one executable '{name}' ({where}); "
                          "`ros2 run` refuses to choose: install only one")
    if hits:
        return hits[0]
    have = ", ".join(listing(package, prefix)) or "none"
    msg = f"package '{package}' has no executable '{name}'; executables it does have: {have}."
    plain = prefix / "lib" / package / name
    deeper = [p for p in executable_paths(package, prefix) if p.name == name]
    if plain.is_file():
        msg += (f" lib/{package}/{name} is installed but not executable: install it with "
                "install(PROGRAMS ...), or make the file executable (chmod +x) in the sources.")
    elif (prefix / "bin" / name).is_file():
        msg += (f" bin/{name} is installed instead, and `ros2 run` looks in lib/{package}/ only: an "
                f"ament_python package needs a setup.cfg with [install] install_scripts=$base/lib/{package} "
                f"(and [develop] script_dir=$base/lib/{package}).")
    elif deeper:
        msg += (f" {deeper[0].relative_to(prefix)} is in a subfolder: `ros2 run` finds it, a launch "
                f"file's Node looks in lib/{package}/ only.")
    raise GraderError(msg)


def command(path: Path, args: Sequence[str] = ()) -> list[str]:
    """argv that starts the executable at ``path`` as ``exec`` would, Python scripts with the ROS Python."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            head = f.read(512)
    except OSError as exc:
        raise GraderError(f"cannot read {path}: {exc.strerror}") from None
    if head.startswith(b"#!"):
        line = head[2:].split(b"\n", 1)[0].decode(errors="replace").strip()
        words = shlex.split(line) if line else []
        if words and Path(words[0]).name == "env":
            words = words[1:]
            while words and words[0].startswith("-"):      # env -S python3 -u
                words = words[1:]
        if words and _PYTHON.fullmatch(Path(words[0]).name):
            return [sys.executable, *words[1:], str(path), *args]
        return [str(path), *args]
    if head.startswith(b"\x7fELF"):
        return [str(path), *args]
    raise GraderError(f"{path.name} is neither a program nor a script with a '#!' line, so `ros2 run` "
                      "cannot start it: make its first line #!/usr/bin/env python3")


def is_python_script(path: Path) -> bool:
    """Whether ``path`` starts with the ROS Python (a Python ``#!`` line)."""
    try:
        return command(path)[0] == sys.executable and Path(path).is_file()
    except GraderError:
        return False
