"""The grader's environment runs student nodes on an rclpy that behaves as current Jazzy's
(issue 35): the MultiThreadedExecutor busy loop of the wheel's rclpy 7.1.6 (ros2/rclpy#1452)
is fixed there by bootstrap, found by behaviour, and an idle MultiThreadedExecutor node with a
rate timer next to the real simulator costs about what a SingleThreadedExecutor's does."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from grader import rclpy_fix
from grader.rosenv import ros_mode
from grader.testing.executor_load import NODE, share

wheels = pytest.mark.skipif(ros_mode() != "wheels", reason="a system ROS install is left as it is")


@wheels
def test_bootstrap_left_the_venv_without_the_busy_loop() -> None:
    state, sentence = rclpy_fix.state()
    assert state in ("fixed", "ok"), sentence
    assert not rclpy_fix.busy_loop_present(sys.executable)


def test_the_edits_apply_once_and_refuse_a_file_they_do_not_know(tmp_path: Path) -> None:
    original = "".join(old for old, _new in rclpy_fix._EDITS)
    target = tmp_path / "executors.py"
    target.write_text(original)
    assert rclpy_fix.apply(target) and rclpy_fix.is_patched(target)
    fixed = target.read_text()
    assert "_grader_queued" in fixed and fixed.count(rclpy_fix.MARK) == len(rclpy_fix._EDITS)
    assert not rclpy_fix.apply(target) and target.read_text() == fixed          # idempotent
    other = tmp_path / "other.py"
    other.write_text("class MultiThreadedExecutor(Executor):\n")
    with pytest.raises(rclpy_fix.RclpyFixError, match="left as it is"):
        rclpy_fix.apply(other)
    assert other.read_text() == "class MultiThreadedExecutor(Executor):\n"


@wheels
@pytest.mark.slow
@pytest.mark.parametrize("scale", [1.0, 2.0])
def test_an_idle_multithreaded_node_costs_about_a_single_threaded_ones(tmp_path: Path, scale: float) -> None:
    node = tmp_path / "node.py"
    node.write_text(NODE)
    single = share([sys.executable, str(node), "single", "-"], scale, 4.0)
    multi = share([sys.executable, str(node), "multi", "rate"], scale, 4.0)
    # unfixed, the multi-threaded node took a whole core on /clock (1.01-1.03 CPU s per s)
    assert multi < max(0.3, 3 * single), (single, multi)
