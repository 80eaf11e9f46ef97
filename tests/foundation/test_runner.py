"""Process runner: real rclpy processes over real DDS, stop escalation, isolation, stdin scripts."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import pytest

from grader.runner import ProcessSpec, RosGraph
from grader.scenario.model import Limits, StdinLine
from grader.testing.ros import rclpy_node, spin_until

NODES = Path(__file__).parent / "nodes"


def node_argv(name: str) -> list[str]:
    return [sys.executable, str(NODES / name)]


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie still answers kill(0); treat it as dead
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.ros
def test_two_processes_exchange_pose_and_set_pen(ros_graph: RosGraph) -> None:
    talker = ros_graph.start(ProcessSpec("talker", node_argv("pose_talker.py")))
    listener = ros_graph.start(ProcessSpec("listener", node_argv("pose_listener.py"),
                                           limits=Limits(wall_s=40)))
    assert listener.wait(45) == 0, listener.errors()
    out = listener.output()
    assert "received" in out and "first y=2.5" in out and "set_pen done=True" in out, out
    time.sleep(0.2)
    assert "set_pen r=10 g=20 b=30 width=4 off=0" in talker.output()
    assert talker.alive()
    assert talker.stop() == 0  # SIGINT → clean rclpy shutdown
    assert not talker.killed


@pytest.mark.ros
def test_stubborn_node_is_killed_with_its_children(ros_graph: RosGraph) -> None:
    spec = ProcessSpec("stubborn", node_argv("stubborn.py"), stop_grace_s=0.5, term_grace_s=0.5)
    proc = ros_graph.start(spec)
    deadline = time.monotonic() + 10
    while "child" not in proc.output() and time.monotonic() < deadline:
        time.sleep(0.05)
    grandchild = int(proc.output().split()[1])
    t0 = time.monotonic()
    proc.stop()
    elapsed = time.monotonic() - t0
    assert proc.killed and proc.returncode == -9
    assert elapsed < 0.5 + 0.5 + 1.0, f"stop took {elapsed:.2f}s"
    time.sleep(0.1)
    assert not _pid_alive(proc.pid)
    assert not _pid_alive(grandchild), "grandchild outlived the run"


@pytest.mark.ros
def test_wall_clock_limit_stops_the_process(ros_graph: RosGraph) -> None:
    proc = ros_graph.start(ProcessSpec("sleeper", [sys.executable, "-c", "import time; time.sleep(60)"],
                                       limits=Limits(wall_s=0.5)))
    assert proc.wait(10) is not None
    assert proc.timed_out


def test_graph_exit_leaves_no_process(tmp_path: Path) -> None:
    with RosGraph(tmp_path) as graph:
        procs = [graph.start(ProcessSpec(f"s{i}", [sys.executable, "-c", "import time; time.sleep(60)"]))
                 for i in range(3)]
    assert all(not _pid_alive(p.pid) for p in procs)


def test_stdin_script_is_typed_line_by_line(ros_graph: RosGraph) -> None:
    proc = ros_graph.start(ProcessSpec("echo", node_argv("echo_stdin.py"), close_stdin=True,
                                       stdin=[StdinLine(line="2.0,7.0", delay=0.1), StdinLine(line="oops", delay=0.1),
                                              StdinLine(line="8.0,3.0", delay=0.1)]))
    assert proc.wait(10) == 0
    out = proc.output()
    assert out.index("'2.0,7.0'") < out.index("'oops'") < out.index("'8.0,3.0'") < out.index("EOF")


def test_resource_limits_apply(ros_graph: RosGraph) -> None:
    code = "import resource; print(resource.getrlimit(resource.RLIMIT_NOFILE)[0], resource.getrlimit(resource.RLIMIT_AS)[0])"
    proc = ros_graph.start(ProcessSpec("limits", [sys.executable, "-c", code],
                                       nofile=77, limits=Limits(memory_mb=2048)))
    assert proc.wait(10) == 0
    assert proc.output().split() == ["77", str(2048 * 2**20)]


def test_memory_hog_is_contained(ros_graph: RosGraph) -> None:
    proc = ros_graph.start(ProcessSpec("hog", [sys.executable, "-c", "x = bytearray(3 * 2**30)"],
                                       limits=Limits(memory_mb=1024)))
    assert proc.wait(20) not in (0, None)
    assert "MemoryError" in proc.errors()


@pytest.mark.ros
def test_two_graphs_do_not_see_each_other(tmp_path: Path) -> None:
    with RosGraph(tmp_path / "a") as a, RosGraph(tmp_path / "b") as b:
        assert a.domain_id != b.domain_id
        a.start(ProcessSpec("talker", node_argv("pose_talker.py")))
        from turtlesim.msg import Pose
        with rclpy_node(a.domain_id, "in_a") as (node_a, ex_a), rclpy_node(b.domain_id, "in_b") as (node_b, ex_b):
            got_a: list = []
            got_b: list = []
            node_a.create_subscription(Pose, "pose", got_a.append, 10)
            node_b.create_subscription(Pose, "pose", got_b.append, 10)
            assert spin_until(ex_a, lambda: len(got_a) >= 5, timeout=20)
            deadline = time.monotonic() + 1.5
            while time.monotonic() < deadline:
                ex_b.spin_once(timeout_sec=0.05)
            assert got_b == []
