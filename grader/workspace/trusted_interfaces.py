"""Trusted copies of the students' interface packages, for the grader's own processes.

The scenario child, the simulator, the recorder and the bag tools are grader processes: they run
outside the students' jail, as the grader's user (root on Gradescope). To call a student's
service, subscribe to a student's topic or record it they import the student's message types.
What a student's build installs under its interface package is not only the code rosidl
generates: its CMake or setup.py may install any Python (an ``__init__.py`` that runs on import)
and any shared library (the typesupport libraries a generated module loads, or one named like a
ROS library on ``LD_LIBRARY_PATH``). So grader processes never load anything of a student's
build: each interface package the student built is built again here, from its definition files
alone, by a CMakeLists.txt and package.xml the grader writes (``rosidl_generate_interfaces`` over
those files, with the packages their fields name as dependencies). The result is what rosidl
generates from those definitions and nothing else; the type names and fields are the student's,
so it talks to the student's nodes as their own build would.

The definitions are the ones the student's build installed (``share/<pkg>/msg|srv|action``), so
the trusted types are exactly the interface the student's nodes were built with, whatever their
CMakeLists listed. They are data to the generators (rosidl parses them); the build still runs in
the build jail. Names are checked before they reach the generated files (a package name as ROS
allows them, file names as rosidl allows them), so nothing of the student's text becomes CMake.

A package the student's build took from an instructor's support build (``reused_from``) needs no
rebuild: that build's own install is trusted (the copy in the student's build area is not: the
student's other packages build with write access to it).

Cost: one colcon build of generated C, C++ and Python per interface package (measured in
``benchmarks/README.md``); the build is content-addressed like every other, so a class whose
interface packages are identical pays for it once per cache.
"""

from __future__ import annotations

import os
import re
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from grader.errors import GraderError
from grader.rosenv import PY_SITE

KINDS = ("msg", "srv", "action")
PACKAGE_NAME = re.compile(r"^[a-z][a-z0-9_]*$")          # REP 144
TYPE_NAME = re.compile(r"^[A-Z][A-Za-z0-9]*$")            # rosidl: message, service, action names
PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
              "int32", "uint32", "int64", "uint64", "string", "wstring"}
#: a definition file larger than this is no interface a lab asks for
MAX_DEFINITION_BYTES = 256 * 1024


@dataclass
class TrustedInterfaces:
    """The trusted builds of a submission's interface packages."""

    prefixes: dict[str, str] = field(default_factory=dict)    # package -> trusted install prefix
    problems: dict[str, str] = field(default_factory=dict)    # package -> why it has none
    build_root: str = ""                                      # the trusted build area ("" if none)
    duration_s: float = 0.0                                   # its colcon build (0 when cached)

    def to_json(self) -> dict:
        return {"prefixes": self.prefixes, "problems": self.problems, "build_root": self.build_root,
                "duration_s": self.duration_s}

    @classmethod
    def from_json(cls, data: dict | None) -> "TrustedInterfaces":
        data = data or {}
        return cls(dict(data.get("prefixes", {})), dict(data.get("problems", {})),
                   data.get("build_root", ""), data.get("duration_s", 0.0))


def definitions(install: Path, package: str) -> dict[str, list[Path]]:
    """The interface definitions a build installed for ``package``: ``{kind: [files]}`` (empty
    when it is no interface package: rosidl generated no Python for it). Only regular files
    inside ``install`` count: a student's build could have made them links to the grader's files
    (rosidl's error messages would then quote them)."""
    inside = install.resolve()
    site = install / PY_SITE / package
    found: dict[str, list[Path]] = {}
    for kind in KINDS:
        if not (site / kind / "__init__.py").is_file():
            continue
        folder = install / "share" / package / kind
        if not folder.is_dir():
            continue
        files = sorted(f for f in folder.glob(f"*.{kind}")
                       if f.is_file() and not f.is_symlink() and f.resolve().is_relative_to(inside))
        if files:
            found[kind] = files
    return found


def field_packages(text: str) -> set[str]:
    """The packages a definition's fields name (``geometry_msgs/Point``, ``pkg/msg/Type``)."""
    out = set()
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or line.startswith("---"):
            continue
        type_ = line.split()[0].split("[", 1)[0]
        if "/" in type_:
            out.add(type_.split("/", 1)[0])
    return out


def _check(package: str, files: dict[str, list[Path]]) -> set[str]:
    """The dependencies of ``package``'s definitions; GraderError for a name rosidl would refuse
    (which is also every name that could say something else in the files written here)."""
    if not PACKAGE_NAME.match(package):
        raise GraderError(f"'{package}' is no valid ROS package name")
    deps: set[str] = set()
    for kind, paths in files.items():
        for f in paths:
            if not TYPE_NAME.match(f.stem):
                raise GraderError(f"{kind}/{f.name}: '{f.stem}' is no valid interface name")
            if f.stat().st_size > MAX_DEFINITION_BYTES:
                raise GraderError(f"{kind}/{f.name} is larger than {MAX_DEFINITION_BYTES // 1024} KiB")
            for dep in field_packages(f.read_text(errors="replace")):
                if not PACKAGE_NAME.match(dep):
                    raise GraderError(f"{kind}/{f.name}: '{dep}' is no valid package name")
                deps.add(dep)
    deps.discard(package)
    return deps


CMAKELISTS = """cmake_minimum_required(VERSION 3.8)
project({package})
# written by grader: the interface definitions of a submission, generated by rosidl, nothing else
find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)
{find}
rosidl_generate_interfaces(${{PROJECT_NAME}}
{files}
{dependencies})
ament_export_dependencies(rosidl_default_runtime)
ament_package()
"""

PACKAGE_XML = """<?xml version="1.0"?>
<package format="3">
  <name>{package}</name>
  <version>0.0.0</version>
  <description>grader's trusted build of a submission's interface definitions</description>
  <maintainer email="grader@example.invalid">grader</maintainer>
  <license>none</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
{depends}  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export><build_type>ament_cmake</build_type></export>
</package>
"""


def write_package(dest: Path, package: str, files: dict[str, list[Path]]) -> None:
    """``dest/<package>``: the grader's CMakeLists.txt and package.xml over copies of ``files``."""
    deps = sorted(_check(package, files))
    pkg = dest / package
    rel = []
    for kind, paths in files.items():
        (pkg / kind).mkdir(parents=True, exist_ok=True)
        for f in paths:
            shutil.copyfile(f, pkg / kind / f.name)
            rel.append(f"{kind}/{f.name}")
    (pkg / "CMakeLists.txt").write_text(CMAKELISTS.format(
        package=package, find="\n".join(f"find_package({d} REQUIRED)" for d in deps),
        files="\n".join(f'  "{r}"' for r in sorted(rel)),
        dependencies=f"  DEPENDENCIES {' '.join(deps)}\n" if deps else ""))
    (pkg / "package.xml").write_text(PACKAGE_XML.format(
        package=package, depends="".join(f"  <depend>{d}</depend>\n" for d in deps)))


def build_trusted_interfaces(result, cache_dir: Path, build_workspace: Callable[..., Any]) -> TrustedInterfaces:
    """Trusted builds of the interface packages ``result`` (a student's ``BuildResult``) built,
    made by ``build_workspace`` (``grader.workspace.build``'s, which calls this: passed in, not
    imported, so the two modules are no circle)."""
    out = TrustedInterfaces()
    staged: list[str] = []
    ws = Path(cache_dir) / f".trusted-interfaces-{os.getpid()}-{time.monotonic_ns()}"
    try:
        for name, pkg in sorted(result.packages.items()):
            if pkg.status != "built":
                continue
            if pkg.reused_from:        # an instructor's build: its own install is trusted as it is
                install = Path(pkg.reused_from) / "install" / name
                if definitions(install, name):
                    out.prefixes[name] = str(install)
                continue
            files = definitions(Path(result.root) / "install" / name, name)
            if not files:
                continue
            try:
                write_package(ws / "src", name, files)
                staged.append(name)
            except (GraderError, OSError) as exc:
                out.problems[name] = f"its interface definitions cannot be built by the grader: {exc}"
        if not staged:
            return out
        trusted = build_workspace(ws, cache_dir=cache_dir, trusted=True)
        out.build_root = str(trusted.root)
        out.duration_s = 0.0 if trusted.cached else trusted.duration_s
        for name in staged:
            pkg = trusted.packages.get(name)
            if pkg is not None and pkg.status == "built":
                out.prefixes[name] = str(trusted.install / name)
            else:
                out.problems[name] = ("the grader's own build of its interface definitions failed: "
                                      + (pkg.reason if pkg is not None else "not built"))
        return out
    finally:
        shutil.rmtree(ws, ignore_errors=True)
