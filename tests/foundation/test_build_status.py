"""Build results a student can trust: each package's status is colcon's own result for it, a
failed package carries its own error line, and its dependants are skipped naming it.

One real colcon build of ``ws_broken`` (its README lists the defect of each package), shared by
the module: a bad ``.srv`` field, a ``.msg`` with an unknown type, an ament_cmake package that
needs rclcpp (absent here), C++ that does not compile, a ``setup.py`` SyntaxError, a package
depending on a failed one, and one good package.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest

from grader.cli import main as grader_main
from grader.errors import GraderError
from grader.workspace import BuildResult, build_workspace

WS = Path(__file__).parent / "ws_broken"

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("build-cache")


@pytest.fixture(scope="module")
def result(cache_dir: Path) -> BuildResult:
    return build_workspace(WS, cache_dir=cache_dir)


def test_status_of_each_package_is_colcons(result: BuildResult) -> None:
    assert {n: p.status for n, p in result.packages.items()} == {
        "bad_cpp": "failed", "broken_setup": "failed", "cpp_driver": "failed", "good_nodes": "built",
        "pose_interfaces": "failed", "turtle_goal": "skipped", "turtle_goal_interfaces": "failed"}
    assert not result.ok and "good_nodes" not in result.failed
    for name in ("turtle_goal_interfaces", "pose_interfaces", "cpp_driver", "bad_cpp"):
        pkg = result.packages[name]
        assert Path(pkg.log).is_file() and f"log: {pkg.log}" in pkg.log_excerpt, name


def test_bad_srv_field_is_reported_with_file_and_line(result: BuildResult) -> None:
    pkg = result.packages["turtle_goal_interfaces"]
    assert pkg.reason.startswith("srv/SetGoal.srv:1: 'x,' is an invalid field name"), pkg.reason
    assert "float64 x, y" in pkg.log_excerpt
    assert "'x,' is an invalid field name" in Path(pkg.log).read_text()   # rosidl said it, not us


def test_unknown_msg_type_points_at_the_line_using_it(result: BuildResult) -> None:
    reason = result.packages["pose_interfaces"].reason
    assert reason.startswith("msg/Target.msg:3: unknown type 'Pose2D'"), reason


def test_dependency_the_machine_lacks_is_named_as_such(result: BuildResult) -> None:
    pkg = result.packages["cpp_driver"]
    assert pkg.reason.startswith("grading machine lacks rclcpp (CMakeLists.txt:4: find_package(rclcpp)"), \
        pkg.reason
    assert pkg.missing_dependencies == ["rclcpp"]
    students = [p.reason for n, p in result.packages.items() if n != "cpp_driver"]
    assert not any("grading machine" in r for r in students), students


def test_compiler_error_is_the_first_one(result: BuildResult) -> None:
    reason = result.packages["bad_cpp"].reason
    assert re.match(r"src/hello\.cpp:[45]:\d+: error: expected ", reason), reason


def test_setup_py_syntax_error_keeps_its_line(result: BuildResult) -> None:
    pkg = result.packages["broken_setup"]
    assert pkg.reason == "setup.py:6: SyntaxError: invalid syntax. Perhaps you forgot a comma?"
    with pytest.raises(GraderError) as err:
        result.argv("broken_setup", "hello")
    assert str(err.value).splitlines()[0] == f"package 'broken_setup' failed to build: {pkg.reason}"


def test_dependant_is_skipped_naming_the_failed_package_and_why(result: BuildResult) -> None:
    pkg = result.packages["turtle_goal"]
    assert pkg.blocked_by == ["turtle_goal_interfaces"]
    with pytest.raises(GraderError) as err:
        result.argv("turtle_goal", "hello")
    first = str(err.value).splitlines()[0]       # what a node_unavailable event shows a student
    assert first.startswith("package 'turtle_goal' was not built: it depends on "
                            "'turtle_goal_interfaces', which failed (srv/SetGoal.srv:1: "
                            "'x,' is an invalid field name"), first


def test_good_package_still_builds_and_runs(result: BuildResult) -> None:
    proc = subprocess.run(result.argv("good_nodes", "hello"), env=result.env(), capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == "hello", proc.stderr


def test_cli_and_json_show_each_package(result: BuildResult, cache_dir: Path, capsys) -> None:
    assert grader_main(["build", str(WS), "--cache-dir", str(cache_dir)]) == 1
    out = capsys.readouterr().out
    assert "cache hit" in out
    assert ("  failed   turtle_goal_interfaces (ament_cmake)\n"
            "    srv/SetGoal.srv:1: 'x,' is an invalid field name") in out
    assert "  skipped  turtle_goal (ament_python)\n    not built: it depends on 'turtle_goal_interfaces'" in out
    assert "  built    good_nodes (ament_python)\n             hello -> lib/good_nodes/hello" in out
    assert "Traceback" not in out
    assert grader_main(["build", str(WS), "--cache-dir", str(cache_dir), "--json"]) == 1
    packages = json.loads(capsys.readouterr().out)["packages"]
    assert packages["cpp_driver"]["missing_dependencies"] == ["rclcpp"]
    assert packages["turtle_goal"]["blocked_by"] == ["turtle_goal_interfaces"]
    assert packages["pose_interfaces"]["reason"] == result.packages["pose_interfaces"].reason
