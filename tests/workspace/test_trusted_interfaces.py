"""Grader processes load nothing of a student's build (grader.workspace.trusted_interfaces,
grader.rosenv.trusted_env): their interface types come from the grader's own build of the
student's definition files.

Fast: what is staged for that build (only the definitions, under the grader's CMakeLists.txt and
package.xml; names rosidl would refuse are refused before they reach those files) and the
environment of a grader process. Slow: the interface package of the fault corpus's
``interface_import`` (its build installs Python that writes a marker in /tmp when the service type
is imported) built for real: a student process of its build runs the planted code; a grader
process started as the scenario child starts the simulator imports the type from the trusted
build and writes nothing.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import pytest

from grader.errors import GraderError
from grader.rosenv import INTERFACE_PATH_VAR, PY_SITE, add_interface_paths, child_env, trusted_env
from grader.workspace.trusted_interfaces import definitions, field_packages, write_package

REPO = Path(__file__).resolve().parents[2]
HOSTILE = REPO / "fixtures" / "faults" / "interface_import" / "src" / "turtle_goal_interfaces"
MARKER = "grader-fault-interface-import-"


def _install(root: Path, package: str, files: dict[str, str], generated: bool = True) -> Path:
    """A made-up install prefix as rosidl leaves it: definitions in share/, Python in site-packages."""
    prefix = root / "install" / package
    for rel, text in files.items():
        kind = rel.split("/")[0]
        (prefix / "share" / package / kind).mkdir(parents=True, exist_ok=True)
        (prefix / "share" / package / rel).write_text(text)
        if generated:
            (prefix / PY_SITE / package / kind).mkdir(parents=True, exist_ok=True)
            (prefix / PY_SITE / package / kind / "__init__.py").write_text("")
    return prefix


def test_only_the_definitions_are_staged_under_the_graders_own_build_files(tmp_path: Path) -> None:
    prefix = _install(tmp_path, "lab_interfaces", {
        "msg/Goal.msg": "# a goal\ngeometry_msgs/Point target\nfloat64 tol 0.1\nstring<=8 name\n",
        "srv/SetGoal.srv": "lab_interfaces/Goal goal\nbuiltin_interfaces/Time[] stamps\n---\nbool success\n",
        "action/Drive.action": "Goal goal\n---\nbool ok\n---\nturtlesim/msg/Pose current\n"})
    (prefix / "share" / "lab_interfaces" / "msg" / "Secret.msg").symlink_to(tmp_path / "rubric.yaml")
    (tmp_path / "rubric.yaml").write_text("hidden: 1\n")
    (prefix / PY_SITE / "lab_interfaces" / "evil.py").write_text("open('/tmp/x', 'w')\n")
    files = definitions(prefix, "lab_interfaces")
    assert {k: [f.name for f in v] for k, v in files.items()} == {
        "msg": ["Goal.msg"], "srv": ["SetGoal.srv"], "action": ["Drive.action"]}    # no link followed
    write_package(tmp_path / "src", "lab_interfaces", files)
    pkg = tmp_path / "src" / "lab_interfaces"
    assert sorted(str(p.relative_to(pkg)) for p in pkg.rglob("*") if p.is_file()) == [
        "CMakeLists.txt", "action/Drive.action", "msg/Goal.msg", "package.xml", "srv/SetGoal.srv"]
    cmake = (pkg / "CMakeLists.txt").read_text()
    assert '"msg/Goal.msg"' in cmake and "DEPENDENCIES builtin_interfaces geometry_msgs turtlesim" in cmake
    assert "find_package(turtlesim REQUIRED)" in cmake and "lab_interfaces REQUIRED" not in cmake
    xml = (pkg / "package.xml").read_text()
    assert "<depend>geometry_msgs</depend>" in xml and "rosidl_interface_packages" in xml


def test_a_package_without_generated_python_is_no_interface_package(tmp_path: Path) -> None:
    prefix = _install(tmp_path, "data_only", {"msg/Goal.msg": "float64 x\n"}, generated=False)
    assert definitions(prefix, "data_only") == {}


@pytest.mark.parametrize("package, rel, text, said", [
    ("Bad-Name", "msg/Goal.msg", "float64 x\n", "no valid ROS package name"),
    ("lab_interfaces", "msg/goal.msg", "float64 x\n", "no valid interface name"),
    ("lab_interfaces", "msg/Goal.msg", "float64 x\nx)file(WRITE${HOME}/p)/Goal g\n", "no valid package name"),
])
def test_names_rosidl_would_refuse_never_reach_the_build_files(tmp_path: Path, package, rel, text, said) -> None:
    prefix = _install(tmp_path, package, {rel: text})
    files = definitions(prefix, package) or {rel.split("/")[0]: [prefix / "share" / package / rel]}
    with pytest.raises(GraderError, match=said):
        write_package(tmp_path / "src", package, files)
    assert not (tmp_path / "src" / package / "CMakeLists.txt").exists()


def test_field_packages() -> None:
    assert field_packages("std_msgs/Header header  # x/y\nfloat64[3] v\npkg/msg/T[<=2] t\n---\nint8 A=1\n") \
        == {"std_msgs", "pkg"}


def test_a_grader_process_gets_nothing_of_the_students_builds(tmp_path: Path) -> None:
    student = tmp_path / "build" / "install" / "lab_interfaces"
    trusted = tmp_path / "trusted" / "install" / "lab_interfaces"
    for p in (student, trusted):
        (p / PY_SITE).mkdir(parents=True)
    base = {"PYTHONPATH": "/opt/ros/jazzy/lib/python3.11/site-packages", "LD_LIBRARY_PATH": "/opt/ros/jazzy/lib",
            "AMENT_PREFIX_PATH": "/opt/ros/jazzy", "PATH": "/usr/bin"}
    theirs = child_env(prefixes=[student], base=base)
    assert theirs["PYTHONPATH"].startswith(str(student / PY_SITE))
    assert theirs["LD_LIBRARY_PATH"].startswith(str(student / "lib"))
    ours = trusted_env(theirs, [student], [trusted])
    assert str(student) not in ours["PYTHONPATH"] and str(student) not in ours["LD_LIBRARY_PATH"]
    assert ours["LD_LIBRARY_PATH"].split(os.pathsep)[-1] == str(trusted / "lib")       # last
    ament = ours["AMENT_PREFIX_PATH"].split(os.pathsep)
    assert ament == [sys.prefix, "/opt/ros/jazzy", str(trusted), str(student)]     # theirs last
    assert ours[INTERFACE_PATH_VAR] == str(trusted / PY_SITE)
    assert str(trusted) not in ours["PYTHONPATH"]          # appended after start-up, never before the venv
    os.environ[INTERFACE_PATH_VAR] = ours[INTERFACE_PATH_VAR]
    try:
        add_interface_paths()
        assert sys.path[-1] == str(trusted / PY_SITE) and INTERFACE_PATH_VAR not in os.environ
    finally:
        sys.path.remove(str(trusted / PY_SITE))


# ----------------------------------------------------------------------------- the real builds
def _markers() -> set[Path]:
    return set(Path("/tmp").glob(f"{MARKER}*"))


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.timeout(900)
def test_a_planted_module_runs_in_student_processes_never_in_grader_processes(tmp_path: Path) -> None:
    from grader.runner import ProcessSpec, RosGraph
    from grader.workspace import build_workspace

    ws = tmp_path / "ws"
    shutil.copytree(HOSTILE, ws / "src" / HOSTILE.name)
    before = _markers()
    build = build_workspace(ws, cache_dir=tmp_path / "cache")
    assert build.ok, {n: p.log_excerpt for n, p in build.packages.items()}
    name = HOSTILE.name
    trusted = Path(build.interfaces.prefixes[name])
    assert not trusted.is_relative_to(build.root) and build.interfaces.problems == {}
    assert (build.install / name / PY_SITE / name / "_planted.py").is_file()       # the student's build planted it
    assert not (trusted / PY_SITE / name / "_planted.py").exists()
    print(f"trusted build of {name}: {build.interfaces.duration_s} s (student build {build.duration_s} s)")
    probe = ("import os, sys, turtle_goal_interfaces.srv as s; from turtle_goal_interfaces.srv import SetGoal; "
             "print('FROM', s.__file__, SetGoal.Request(x=1.0).x, os.getuid())")
    with RosGraph(tmp_path / "graph", prefixes=build.prefixes(), interfaces=build.interface_prefixes()) as graph:
        student = graph.start(ProcessSpec("student", [sys.executable, "-c", probe], untrusted=True))
        grader = graph.start(ProcessSpec("grader", [sys.executable, "-c",
                                                    "from grader.rosenv import add_interface_paths; "
                                                    f"add_interface_paths(); {probe}"]))
        assert student.wait(60) == 0 and grader.wait(60) == 0, student.errors() + grader.errors()
    # the student's process ran the planted module (in its jail's own /tmp when the jail is on)
    assert "PLANTED IMPORT" in student.errors() and f"FROM {build.install / name}" in student.output()
    assert "PLANTED IMPORT" not in grader.errors(), grader.errors()
    assert f"FROM {trusted / PY_SITE}" in grader.output() and " 1.0 " in grader.output()
    for marker in _markers() - before:      # without a jail the student's process writes the machine's /tmp
        assert "add_interface_paths" not in marker.read_text(), marker.read_text()    # never the grader's
        marker.unlink()
    # a cached build keeps the trusted one
    again = build_workspace(ws, cache_dir=tmp_path / "cache")
    assert again.cached and again.interfaces.prefixes == build.interfaces.prefixes
