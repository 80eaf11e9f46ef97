"""`grader sim` / `python -m grader.sim` argument handling and the argv helper (no ROS)."""

from __future__ import annotations

import sys

import pytest

from grader import cli
from grader.sim import (SAVE_CANVAS_SERVICE, all_service_event_topics, service_event_topic,
                        sim_argv)
from grader.sim.cli import main, ros_argv


def parse(*argv: str):
    return cli.build_parser().parse_args(["sim", *argv])


def test_sim_subcommand_is_registered() -> None:
    args = parse("--canvas-out", "out.png", "--holonomic", "--background", "1", "2", "3",
                 "--ros-args", "-r", "__ns:=/sim1")
    assert args.func.__name__ == "run_from_args"
    assert str(args.canvas_out) == "out.png" and args.holonomic
    assert ros_argv(args) == ["grader-sim", "--ros-args", "-p", "holonomic:=true",
                              "-p", "background_r:=1", "-p", "background_g:=2",
                              "-p", "background_b:=3", "--ros-args", "-r", "__ns:=/sim1"]


def test_plain_run_passes_no_ros_args() -> None:
    assert ros_argv(parse()) == ["grader-sim"]


def test_background_out_of_range_is_a_user_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--background", "0", "300", "0"]) == 2
    assert "grader: error: --background values must be 0..255, got 300" in capsys.readouterr().err
    assert cli.main(["sim", "--background", "-1", "0", "0"]) == 2


def test_canvas_out_directory_is_rejected(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--canvas-out", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_sim_argv() -> None:
    assert sim_argv() == [sys.executable, "-m", "grader.sim"]
    assert sim_argv("c.png", ["--ros-args", "-r", "__ns:=/a"], holonomic=True,
                    background=(1, 2, 3)) == [
        sys.executable, "-m", "grader.sim", "--canvas-out", "c.png", "--holonomic",
        "--background", "1", "2", "3", "--ros-args", "-r", "__ns:=/a"]


def test_service_event_topic_names() -> None:
    assert SAVE_CANVAS_SERVICE == "/turtlesim/save_canvas"
    assert service_event_topic("/turtle1/teleport_absolute") == \
        "/turtle1/teleport_absolute/_service_event"
    assert all_service_event_topics(["turtle1"]) == [
        "/clear/_service_event", "/reset/_service_event", "/spawn/_service_event",
        "/kill/_service_event", "/turtle1/set_pen/_service_event",
        "/turtle1/teleport_absolute/_service_event", "/turtle1/teleport_relative/_service_event"]
