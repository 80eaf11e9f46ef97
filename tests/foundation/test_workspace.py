"""Workspace builder: colcon builds of ament_python + ament_cmake interface packages, caching,
archives, and running executables through the runner. Broken packages: test_build_status.py."""

from __future__ import annotations

import tarfile
from pathlib import Path

import pytest

from grader.cli import main as grader_main
from grader.errors import GraderError
from grader.runner import ProcessSpec, RosGraph
from grader.workspace import build_workspace

WS = Path(__file__).parent / "ws"

# the module's first test builds an interface package with CMake (its fixture counts against the
# test's timeout): about 190 s beside a busy make test, over the 300 s default once when other
# sessions shared the two cores
pytestmark = pytest.mark.timeout(900)


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("build-cache")


@pytest.fixture(scope="module")
def built(cache_dir: Path):
    return build_workspace(WS, cache_dir=cache_dir)


@pytest.mark.slow
def test_builds_python_and_interface_packages(built) -> None:
    assert built.ok, {n: p.log_excerpt for n, p in built.packages.items()}
    assert built.packages["demo_interfaces"].build_type == "ament_cmake"
    assert built.packages["demo_nodes"].executables == {     # what `ros2 pkg executables` lists
        "make_goal": "lib/demo_nodes/make_goal", "hello": "lib/demo_nodes/hello"}
    assert not (WS / "build").exists() and not (WS / "install").exists(), "built inside the source tree"


@pytest.mark.slow
def test_runs_executable_that_uses_custom_action_type(built, tmp_path: Path) -> None:
    with RosGraph(tmp_path, prefixes=built.prefixes()) as graph:
        proc = graph.start(ProcessSpec("make_goal", built.argv("demo_nodes", "make_goal",
                                                               args=["--ros-args", "-p", "k:=1"]),
                                       untrusted=True))
        assert proc.wait(30) == 0, proc.errors()
    # started as `ros2 run` starts it: the installed console script, argv[0] its path
    assert f"made goal 2.0,7.0 tol=0.1 argv0={built.install}/demo_nodes/lib/demo_nodes/make_goal" in proc.output()
    assert "goal x=2.0 start.x=5.5" in proc.errors()  # rclpy logs to stderr


@pytest.mark.slow
def test_entry_point_found_by_module_whatever_its_script_name(built, tmp_path: Path) -> None:
    argv = built.argv("demo_nodes", module="demo_nodes.hello:run")
    with RosGraph(tmp_path, prefixes=built.prefixes()) as graph:
        proc = graph.start(ProcessSpec("hello", argv, untrusted=True))
        assert proc.wait(20) == 0
    assert proc.output().strip() == "hello"


@pytest.mark.slow
def test_rebuild_of_unchanged_sources_is_a_cache_hit(built, cache_dir: Path, tmp_path: Path) -> None:
    # same content from an archive in another place → same digest, no colcon run
    archive = tmp_path / "ws.tar.gz"
    with tarfile.open(archive, "w:gz") as tf:
        tf.add(WS, arcname="my_ws")
    again = build_workspace(archive, cache_dir=cache_dir)
    assert again.cached and again.digest == built.digest


@pytest.mark.slow
def test_missing_executable_lists_the_ones_that_exist(built) -> None:
    with pytest.raises(GraderError) as err:
        built.argv("demo_nodes", "goal_publisher")
    msg = str(err.value)
    assert "no executable 'goal_publisher'" in msg and "make_goal" in msg and "hello" in msg
    with pytest.raises(GraderError, match="package 'turtle_control' is not in the submission"):
        built.argv("turtle_control", "turtle_control_node")


def test_not_a_workspace_is_a_clear_error(tmp_path: Path, capsys) -> None:
    (tmp_path / "empty").mkdir()
    assert grader_main(["build", str(tmp_path / "empty"), "--cache-dir", str(tmp_path / "c")]) == 2
    assert "no ROS package (package.xml) found" in capsys.readouterr().err
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(GraderError, match="not a readable archive"):
        build_workspace(bad, cache_dir=tmp_path / "c")


def test_archive_members_outside_the_tree_are_skipped_with_a_warning(tmp_path: Path) -> None:
    """Zip-slip, absolute paths and links: never written outside, never followed, each reported."""
    import tarfile
    import zipfile

    from grader.workspace.source import stage_sources
    evil = tmp_path / "evil.zip"
    with zipfile.ZipFile(evil, "w") as zf:
        zf.writestr("../../etc/x/package.xml", "<package><name>x</name></package>")
        zf.writestr("/tmp/grader-abs-evil.txt", "absolute")
        zf.writestr("ws/src/p/package.xml", "<package><name>p</name><export><build_type>ament_python</build_type></export></package>")
    staged = stage_sources(evil, tmp_path / "s1" / "src", tmp_path / "s1")
    assert [p.name for p in staged.packages] == ["p"]
    assert any("'../../etc/x/package.xml'" in w and "outside" in w for w in staged.warnings)
    assert any("/tmp/grader-abs-evil.txt" in w for w in staged.warnings)
    assert not Path("/tmp/grader-abs-evil.txt").exists() and not (tmp_path.parent / "etc").exists()
    with pytest.raises(GraderError, match="no ROS package"):     # nothing usable left: one clear error
        only_evil = tmp_path / "only.zip"
        with zipfile.ZipFile(only_evil, "w") as zf:
            zf.writestr("../../etc/x/package.xml", "<package><name>x</name></package>")
        build_workspace(only_evil, cache_dir=tmp_path / "c")
    # a link in a folder submission and in a .tar.gz is skipped, not followed
    pkg = tmp_path / "folder" / "src" / "p"
    pkg.mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>p</name></package>")
    (pkg / "leak").symlink_to("/etc/passwd")
    staged = stage_sources(tmp_path / "folder", tmp_path / "s2" / "src", tmp_path / "s2")
    assert not (tmp_path / "s2" / "src" / "p" / "leak").exists()
    assert any("symbolic link" in w and "leak" in w for w in staged.warnings)
    tgz = tmp_path / "sub.tar.gz"
    with tarfile.open(tgz, "w:gz") as tf:
        tf.add(tmp_path / "folder", arcname="ws")
    staged = stage_sources(tgz, tmp_path / "s3" / "src", tmp_path / "s3")
    assert any("link" in w and "/etc/passwd" in w for w in staged.warnings)
    assert not (tmp_path / "s3" / "src" / "p" / "leak").exists()
