"""Executables found and started as ``ros2 run`` / ``ros2 launch`` find and start them
(grader.workspace.executables), for every package style a student may use.

The lookup on its own (made-up install prefixes, no colcon), then ``tests/workspace/ws`` built for
real with colcon: an ament_python console script (styles_py), an ament_cmake ``install(PROGRAMS)``
script (styles_cmake), an ament_cmake_python mixed package with its own Python module, a .srv and
a launch file (styles_mixed), a C++ program that needs no ROS library (styles_cpp), and two that
cannot build here: a C++ node needing rclcpp (styles_rclcpp) and a mixed package whose module is
named like its interfaces' (styles_clash). Each buildable one is started from the launch file and
from rubric ``executable:`` processes, by the scenario runner in its sandbox.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from grader.cli import main as grader_main
from grader.errors import GraderError
from grader.rosenv import PY_SITE
from grader.workspace.executables import (INDEX, command, executable_paths, find_executable, listing,
                                          package_prefix)

#: the build of tests/workspace/ws (rosidl, C++ and five CMake configures) takes ~3 min on 2 free cores
pytestmark = pytest.mark.timeout(900)

WS = Path(__file__).parent / "ws"
STYLES = {"styles_py": "py_talker", "styles_cmake": "cmake_talker", "styles_mixed": "mixed_node",
          "styles_cpp": "cpp_hello"}
TOPICS = {"/styles/py": "console script", "/styles/cmake": "install(PROGRAMS)",
          "/styles/mixed": "module + srv Echo"}


# ------------------------------------------------------------------ the lookup on its own
def _package(prefix: Path, name: str, files: dict[str, tuple[str, int]], *, indexed: bool = True) -> Path:
    """An install prefix holding ``name`` (``files``: path under the prefix -> (text, mode))."""
    if indexed:
        (prefix / INDEX).mkdir(parents=True, exist_ok=True)
        (prefix / INDEX / name).write_text("")
    for rel, (text, mode) in files.items():
        path = prefix / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        path.chmod(mode)
    return prefix


def test_prefix_comes_from_the_ament_index_first_prefix_wins(tmp_path: Path) -> None:
    overlay = _package(tmp_path / "overlay", "pkg", {"lib/pkg/node": ("#!/bin/sh\n", 0o755)})
    underlay = _package(tmp_path / "underlay", "pkg", {"lib/pkg/node": ("#!/bin/sh\n", 0o755),
                                                       "lib/pkg/old": ("#!/bin/sh\n", 0o755)})
    unindexed = _package(tmp_path / "plain", "pkg", {"lib/pkg/ghost": ("#!/bin/sh\n", 0o755)}, indexed=False)
    assert package_prefix("pkg", [unindexed, overlay, underlay]) == overlay
    assert find_executable("pkg", "node", [unindexed, overlay, underlay]) == overlay / "lib/pkg/node"
    with pytest.raises(GraderError, match="has no executable 'old'; executables it does have: node"):
        find_executable("pkg", "old", [overlay, underlay])         # the overlay hides the underlay
    with pytest.raises(GraderError, match="package 'pkg' not found: no install prefix has it in the ament index"):
        find_executable("pkg", "ghost", [unindexed])


def test_executables_are_what_ros2_pkg_executables_lists(tmp_path: Path) -> None:
    prefix = _package(tmp_path, "pkg", {
        "lib/pkg/talker": ("#!/usr/bin/env python3\n", 0o755),
        "lib/pkg/tools/helper": ("#!/bin/sh\n", 0o755),          # a subfolder: ros2 run finds it
        "lib/pkg/.hidden/secret": ("#!/bin/sh\n", 0o755),         # dot folders are skipped
        "lib/pkg/data.yaml": ("a: 1\n", 0o644),                   # not executable
        "lib/pkg/twice/dup": ("#!/bin/sh\n", 0o755),
        "lib/pkg/again/dup": ("#!/bin/sh\n", 0o755),
        "lib/other/foreign": ("#!/bin/sh\n", 0o755),
        "bin/no_cfg": ("#!/bin/sh\n", 0o755)})                  # setup.py without setup.cfg puts it here
    assert listing("pkg", prefix) == ["dup", "dup", "helper", "talker"]
    assert [p.name for p in executable_paths("pkg", prefix, nested=False)] == ["talker"]
    assert find_executable("pkg", "helper", [prefix]) == prefix / "lib/pkg/tools/helper"
    with pytest.raises(GraderError, match=r"tools/helper is in a subfolder: `ros2 run` finds it, a launch"):
        find_executable("pkg", "helper", [prefix], nested=False)
    with pytest.raises(GraderError, match=r"more than one executable 'dup' \(lib/pkg/again/dup, lib/pkg/twice/dup\)"):
        find_executable("pkg", "dup", [prefix])
    with pytest.raises(GraderError, match=r"lib/pkg/data.yaml is installed but not executable: install it with "
                                          r"install\(PROGRAMS"):
        find_executable("pkg", "data.yaml", [prefix])
    with pytest.raises(GraderError, match=r"bin/no_cfg is installed instead, and `ros2 run` looks in lib/pkg/ only: "
                                          r"an ament_python package needs a setup.cfg with \[install\] "
                                          r"install_scripts=\$base/lib/pkg"):
        find_executable("pkg", "no_cfg", [prefix])


@pytest.mark.parametrize("first_line, expected", [
    ("#!/usr/bin/env python3", ["{python}", "{script}", "a"]),
    ("#!/usr/bin/python3 -u", ["{python}", "-u", "{script}", "a"]),     # a ROS machine's python3
    ("#!/usr/bin/env -S python3 -O", ["{python}", "-O", "{script}", "a"]),
    ("#!/opt/somewhere/venv/bin/python", ["{python}", "{script}", "a"]),  # what setuptools writes
    ("#!/bin/sh", ["{script}", "a"]),
    ("#!/usr/bin/env bash", ["{script}", "a"]),
])
def test_scripts_start_by_their_shebang_python_ones_with_the_ros_python(tmp_path: Path, first_line: str,
                                                                        expected: list[str]) -> None:
    script = tmp_path / "node"
    script.write_text(first_line + "\nprint('x')\n")
    script.chmod(0o755)
    assert command(script, ["a"]) == [x.format(python=sys.executable, script=script) for x in expected]


def test_binaries_run_directly_and_a_file_without_shebang_is_refused(tmp_path: Path) -> None:
    binary = Path(shutil.which("true") or "/bin/true").resolve()
    assert command(binary, ["x"]) == [str(binary), "x"]
    bare = tmp_path / "bare"
    bare.write_text("import rclpy\n")
    with pytest.raises(GraderError, match="neither a program nor a script with a '#!' line.*#!/usr/bin/env python3"):
        command(bare)


# ------------------------------------------------------------------ real builds of each style
@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("build-cache")


@pytest.fixture(scope="module")
def built(cache_dir: Path):
    from grader.workspace import build_workspace
    return build_workspace(WS, cache_dir=cache_dir)


@pytest.mark.slow
def test_each_style_builds_and_lists_its_executables(built, cache_dir: Path, capsys) -> None:
    status = {n: p.status for n, p in built.packages.items()}
    assert status == {"styles_clash": "failed", "styles_cmake": "built", "styles_cpp": "built",
                      "styles_mixed": "built", "styles_py": "built", "styles_rclcpp": "failed"}, \
        {n: p.log_excerpt for n, p in built.packages.items()}
    for package, exe in STYLES.items():       # install(FILES) not_a_program is not an executable
        assert built.packages[package].executables == {exe: f"lib/{package}/{exe}"}
    assert built.packages["styles_rclcpp"].reason.startswith("grading machine lacks rclcpp"), \
        built.packages["styles_rclcpp"].reason
    assert built.packages["styles_clash"].reason.startswith(
        "CMakeLists.txt:7: ament_python_install_package(styles_clash) installs a Python package named like "
        "the one rosidl_generate_interfaces() installs"), built.packages["styles_clash"].reason
    # the module path the scripts import from is where colcon's own hook puts it on PYTHONPATH
    hook = built.install / "styles_mixed" / "share" / "styles_mixed" / "hook" / "pythonpath.dsv"
    assert hook.read_text().strip() == f"prepend-non-duplicate;PYTHONPATH;{PY_SITE}"
    assert grader_main(["build", str(WS), "--cache-dir", str(cache_dir), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert {n: p["executables"] for n, p in doc["packages"].items() if p["executables"]} == \
        {p: {e: f"lib/{p}/{e}"} for p, e in STYLES.items()}


@pytest.mark.slow
def test_each_style_runs_as_ros2_run_starts_it(built) -> None:
    """Outside any scenario: the argv the grader uses, with the build's environment."""
    env = built.env()
    proc = subprocess.Popen(built.argv("styles_cpp", "cpp_hello", args=["one", "two"]), env=env,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "hello from C++: one two"
    finally:
        proc.terminate()
        proc.wait(10)
    # the mixed package's script runs with the ROS Python, which finds its module and service type
    argv = built.argv("styles_mixed", "mixed_node")
    assert argv[0] == sys.executable and argv[1].endswith("install/styles_mixed/lib/styles_mixed/mixed_node")
    code = "from styles_mixed_tools.words import WORD; from styles_mixed.srv import Echo; print(WORD, Echo.__name__)"
    done = subprocess.run([argv[0], "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == "module Echo", done.stderr


def _scenario(processes: list[dict]):
    from grader.scenario.model import Scenario

    steps = [{"id": f"hear_{t.rsplit('/', 1)[-1]}", "timeout": 30,
              "until": {"condition": "messages", "topic": t, "count": 3}} for t in TOPICS]
    return Scenario.model_validate({"sim": False, "processes": processes, "steps": steps,
                                    "limits": {"wall_s": 120}})


def _run(name: str, scenario, built, out: Path) -> tuple[dict, dict]:
    from grader.bag.frames import load_frames
    from grader.scenario import resolve, run_scenario

    run = resolve(name, scenario, built)
    record = run_scenario(run, out).to_json()
    frames = load_frames(out / "bag")
    return record, frames


def _heard(frames: dict) -> dict[str, set[str]]:
    return {t: set(frames[t]["data"]) if t in frames else set() for t in TOPICS}


def _events(frames: dict, kind: str) -> list[dict]:
    return [e for e in map(json.loads, frames["/grader/events"]["data"]) if e["event"] == kind]


@pytest.mark.slow
@pytest.mark.ros
def test_every_style_starts_from_a_launch_file(built, tmp_path: Path) -> None:
    record, frames = _run("launch", _scenario([{"name": "app", "package": "styles_mixed",
                                                "launch": "styles.launch.py"}]), built, tmp_path)
    assert record["errors"] == [], record["errors"]
    assert [s["ended_by"] for s in record["steps"]] == ["condition"] * 3, record["steps"]
    assert _heard(frames) == {t: {text} for t, text in TOPICS.items()}
    started = {e["process"] for e in _events(frames, "node_started")}
    assert started == {"app.py_talker", "app.cmake_talker", "app.mixed_node", "app.cpp_hello"}
    assert (tmp_path / "logs" / "app.cpp_hello.stdout.log").read_text().strip() == "hello from C++: from-launch"
    assert not _events(frames, "node_unavailable")


@pytest.mark.slow
@pytest.mark.ros
def test_every_style_starts_from_rubric_executables_and_a_cpp_node_says_what_it_needs(built, tmp_path: Path) -> None:
    processes = [{"name": exe, "package": pkg, "executable": exe} for pkg, exe in STYLES.items()]
    processes.append({"name": "cpp_node", "package": "styles_rclcpp", "executable": "rclcpp_node"})
    record, frames = _run("exec", _scenario(processes), built, tmp_path)
    assert [s["ended_by"] for s in record["steps"]] == ["condition"] * 3, record["steps"]
    assert _heard(frames) == {t: {text} for t, text in TOPICS.items()}
    assert (tmp_path / "logs" / "cpp_hello.stdout.log").read_text().strip() == "hello from C++:"
    (missing,) = _events(frames, "node_unavailable")
    assert missing["process"] == "cpp_node"
    assert missing["error"].startswith("package 'styles_rclcpp' failed to build: grading machine lacks rclcpp"), missing
    # an item that needed the C++ node says so, in one sentence naming what is needed
    from grader.grading.analysis import analyze_item
    from grader.rubric import load_rubric

    item = load_rubric(Path(__file__).resolve().parents[2] / "rubrics" / "goal_setter.yaml").item("service.success")
    finding = analyze_item(item, frames)
    assert finding.status == "fail"
    assert "Could not run cpp_node: package 'styles_rclcpp' failed to build: grading machine lacks rclcpp" \
        in finding.feedback, finding.feedback


@pytest.mark.slow
def test_a_launch_file_node_that_needs_rclcpp_says_so(built) -> None:
    from grader.scenario import resolve

    run = resolve("launch", _scenario([{"name": "app", "package": "styles_mixed",
                                        "launch": "needs_rclcpp.launch.py"}]), built)
    talker, cpp = run.launched["app"]
    assert talker.argv and not talker.error
    assert cpp.error.startswith("needs_rclcpp.launch.py:9: package 'styles_rclcpp' failed to build: "
                                "grading machine lacks rclcpp"), cpp.error


@pytest.mark.slow
def test_a_launch_file_an_ament_cmake_package_does_not_install_says_how_to_install_it(built) -> None:
    from grader.scenario import resolve

    run = resolve("launch", _scenario([{"name": "app", "package": "styles_cmake",
                                        "launch": "talker.launch.py"}]), built)
    (note,) = run.notes["app"]
    assert note.startswith("talker.launch.py is not installed by styles_cmake's CMakeLists.txt (add "
                           "install(DIRECTORY launch DESTINATION share/${PROJECT_NAME}))"), note
    assert run.launched["app"][0].argv                 # still run, from the sources



def test_a_package_outside_the_submission_is_found_in_a_sourced_ros(tmp_path: Path, monkeypatch) -> None:
    """`ros2 run` finds a package of the sourced ROS (an underlay) as well as the workspace's."""
    from grader.workspace.build import BuildResult, PackageBuild

    ros = _package(tmp_path / "opt_ros", "demo_nodes_py", {"lib/demo_nodes_py/talker": ("#!/usr/bin/env python3\n", 0o755)})
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(ros))
    build = BuildResult("sub", "d", tmp_path / "area", {"mine": PackageBuild("mine", "ament_python", "built")})
    assert build.argv("demo_nodes_py", "talker") == [sys.executable, str(ros / "lib/demo_nodes_py/talker")]
    with pytest.raises(GraderError, match=r"package 'mine' is built but not in the ament index .* "
                                          r"data_files=\[\('share/ament_index/resource_index/packages'"):
        build.argv("mine", "node")
    with pytest.raises(GraderError, match=r"package 'other' is not in the submission \(packages found: mine\)"):
        build.argv("other", "node")


def test_stray_executables_are_those_under_another_packages_lib_folder(tmp_path: Path) -> None:
    """A package renamed in setup.py whose setup.cfg still installs its scripts into
    lib/<old name>/: ros2 run finds them under neither name, and the contract check needs to
    know the package has nodes at all (first_nodes diagnosis other_package)."""
    from grader.workspace.executables import listing, stray_executables

    prefix = tmp_path / "install" / "my_package"
    for rel in ("lib/my_first_package/my_first_node", "lib/python3.11/site-packages/x.py"):
        path = prefix / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("#!/usr/bin/env python3\n")
        path.chmod(0o755)
    assert listing("my_package", prefix) == []
    assert stray_executables("my_package", prefix) == ["my_first_package/my_first_node"]
    assert stray_executables("my_first_package", prefix) == []
